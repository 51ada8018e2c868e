"""Measurement model of the prognoser: feature = h(severity) + v, v ~ N(0, sigma(severity)^2).

Conventions
-----------
- ``severity`` is normalised (0 healthy, 1.0 = failure threshold), dimensionless.
- ``feature`` is in the unit of the health feature it models (e.g. ``F_MTWEAR`` in m); the noise
  standard deviation ``sigma(s) = noise_std + noise_slope * s`` is in the same unit.
- The noise may grow with severity (``noise_slope`` >= 0): the features' scatter around h
  grows from onset to failure (docs/TUNING.md, Training). A constant sigma then overrates the
  first flights' noise, which carry the growth rate, and underrates the last ones'.
- ``h`` is a polynomial in severity (ascending coefficients ``c_0 + c_1 s + ...``) fitted by least
  squares on a design campaign's (severity, feature) pairs. It must be strictly monotone on its
  ``severity_range`` (otherwise severity is not identifiable from the feature); outside that range
  it is continued linearly with the end slope, so it stays monotone for particles that overshoot.
- Persisted as versioned JSON (``"version": 2``; version 1, without ``noise_slope``, is still
  read), never pickled.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import minimize

from .constants import CONSTANTS

__all__ = ["MeasurementModel"]

_VERSION = 2
_READABLE_VERSIONS = (1, 2)


@dataclass(frozen=True)
class MeasurementModel:
    """Monotone polynomial feature model with Gaussian noise.

    Attributes
    ----------
    coefficients:
        Ascending polynomial coefficients of h [feature unit per severity^j].
    noise_std:
        Standard deviation of the feature around h(severity) at severity 0 [feature unit], > 0.
    severity_range:
        (low, high) where the polynomial is used [-]; linear continuation outside.
    noise_slope:
        Growth of the standard deviation per unit severity [feature unit], >= 0; severity is
        clipped to ``severity_range`` there.
    """

    coefficients: tuple[float, ...]
    noise_std: float
    severity_range: tuple[float, float] = (0.0, 1.5)
    noise_slope: float = 0.0
    if TYPE_CHECKING:  # derived in __post_init__, not fields: declared for the type checker
        _lo_val: float = field(init=False)
        _hi_val: float = field(init=False)
        _lo_slope: float = field(init=False)
        _hi_slope: float = field(init=False)
        _grid_s: NDArray[np.float64] = field(init=False)
        _grid_z: NDArray[np.float64] = field(init=False)
        _increasing: bool = field(init=False)

    def __post_init__(self) -> None:
        coefs = tuple(float(c) for c in self.coefficients)
        if len(coefs) < 2 or not all(math.isfinite(c) for c in coefs):
            raise ValueError("coefficients need at least 2 finite values (constant and slope)")
        object.__setattr__(self, "coefficients", coefs)
        if not (math.isfinite(self.noise_std) and self.noise_std > 0):
            raise ValueError(f"noise_std must be finite and > 0, got {self.noise_std!r}")
        lo, hi = (float(v) for v in self.severity_range)
        if not (math.isfinite(lo) and math.isfinite(hi) and hi > lo):
            raise ValueError("severity_range must be finite with high > low")
        object.__setattr__(self, "severity_range", (lo, hi))
        if not (math.isfinite(self.noise_slope) and self.noise_slope >= 0):
            raise ValueError(f"noise_slope must be finite and >= 0, got {self.noise_slope!r}")
        object.__setattr__(self, "noise_slope", float(self.noise_slope))
        grid = np.linspace(lo, hi, CONSTANTS.inversion_grid)
        slope = self._poly_derivative(grid)
        if not (np.all(slope > 0) or np.all(slope < 0)):
            raise ValueError("h(severity) is not strictly monotone on severity_range")
        # cached end values and slopes for the linear continuation, and the inversion table
        object.__setattr__(self, "_lo_val", float(self._poly(np.array([lo]))[0]))
        object.__setattr__(self, "_hi_val", float(self._poly(np.array([hi]))[0]))
        object.__setattr__(self, "_lo_slope", float(slope[0]))
        object.__setattr__(self, "_hi_slope", float(slope[-1]))
        object.__setattr__(self, "_grid_s", grid)
        object.__setattr__(self, "_grid_z", self._poly(grid))
        object.__setattr__(self, "_increasing", bool(slope[0] > 0))

    # -- construction -----------------------------------------------------------------------
    @classmethod
    def fit(
        cls,
        severity: ArrayLike,
        feature: ArrayLike,
        *,
        degree: int = 2,
        severity_range: tuple[float, float] | None = None,
        noise: str = "constant",
    ) -> MeasurementModel:
        """Least-squares fit of h from (severity, feature) pairs.

        Parameters
        ----------
        severity, feature:
            Arrays of shape (n,), severity normalised (threshold 1.0).
        degree:
            Highest polynomial degree tried (>= 1); if the fit is not monotone on
            ``severity_range`` the degree is lowered until it is (degree 1 always is, unless the
            slope is zero).
        severity_range:
            Range where the polynomial is trusted; default (min(0, s_min), max(1.5, s_max)).
        noise:
            ``"constant"``: ``noise_std`` is the residual standard deviation (ddof = number of
            coefficients). ``"linear"``: ``noise_std`` and ``noise_slope`` maximise the Gaussian
            likelihood of the residuals with sigma(s) = noise_std + noise_slope s.

        Returns
        -------
        MeasurementModel
            Of the highest degree that is monotone on ``severity_range``.
        """
        if noise not in ("constant", "linear"):
            raise ValueError(f"noise must be 'constant' or 'linear', got {noise!r}")
        s = np.asarray(severity, dtype=float).ravel()
        z = np.asarray(feature, dtype=float).ravel()
        if s.shape != z.shape:
            raise ValueError("severity and feature must have the same length")
        if not (np.all(np.isfinite(s)) and np.all(np.isfinite(z))):
            raise ValueError("severity and feature must be finite")
        if isinstance(degree, bool) or not isinstance(degree, int) or degree < 1:
            raise ValueError("degree must be an int >= 1")
        if severity_range is None:
            severity_range = (
                min(0.0, float(s.min(initial=0.0))),
                max(1.5, float(s.max(initial=0.0))),
            )
        last_error: ValueError | None = None
        for deg in range(degree, 0, -1):
            n_coef = deg + 1
            if s.size <= n_coef or np.unique(s).size < n_coef:
                continue
            vander = np.vander(s, n_coef, increasing=True)
            coefs, *_ = np.linalg.lstsq(vander, z, rcond=None)
            resid = z - vander @ coefs
            sigma = float(np.sqrt(np.sum(resid**2) / (s.size - n_coef)))
            sigma = max(sigma, 1e-12 * max(1.0, float(np.abs(z).max())))
            slope = 0.0
            if noise == "linear":
                lo_s, hi_s = severity_range
                sigma, slope = _fit_linear_noise(np.clip(s, lo_s, hi_s), resid, sigma)
            try:
                return cls(tuple(coefs), sigma, severity_range, slope)
            except ValueError as exc:  # not monotone: try a lower degree
                last_error = exc
        raise ValueError(
            f"cannot fit a monotone measurement model: {last_error or 'too few points'}"
        )

    @classmethod
    def identity(cls, noise_std: float) -> MeasurementModel:
        """feature = severity + v: for a health indicator already normalised to threshold 1."""
        return cls((0.0, 1.0), float(noise_std), (0.0, 1.5))

    # -- evaluation -------------------------------------------------------------------------
    def _poly(self, s: NDArray[np.float64]) -> NDArray[np.float64]:
        out = np.full_like(s, self.coefficients[-1])
        for c in self.coefficients[-2::-1]:
            out *= s
            out += c
        return out

    def _poly_derivative(self, s: NDArray[np.float64]) -> NDArray[np.float64]:
        d = [j * c for j, c in enumerate(self.coefficients)][1:]
        out = np.full_like(s, d[-1])
        for c in d[-2::-1]:
            out *= s
            out += c
        return out

    def predict(self, severity: ArrayLike) -> NDArray[np.float64]:
        """Expected feature h(severity), vectorised; linear continuation outside the range."""
        s = np.asarray(severity, dtype=float)
        lo, hi = self.severity_range
        sc = np.clip(s, lo, hi)
        out = self._poly(sc)
        excess = s - sc
        out += np.where(excess > 0, self._hi_slope, self._lo_slope) * excess
        return out

    def derivative(self, severity: ArrayLike) -> NDArray[np.float64]:
        """dh/dseverity [feature unit], vectorised."""
        s = np.asarray(severity, dtype=float)
        lo, hi = self.severity_range
        return np.where(
            s > hi,
            self._hi_slope,
            np.where(s < lo, self._lo_slope, self._poly_derivative(np.clip(s, lo, hi))),
        )

    def noise_at(self, severity: ArrayLike) -> NDArray[np.float64]:
        """Noise standard deviation sigma(severity) [feature unit], vectorised."""
        lo, hi = self.severity_range  # minimum/maximum: np.clip's overhead is the update's
        s = np.minimum(np.maximum(np.asarray(severity, dtype=float), lo), hi)
        return self.noise_std + self.noise_slope * s

    def invert(self, feature: ArrayLike) -> NDArray[np.float64]:
        """Severity whose expected feature is ``feature`` (table lookup + linear continuation)."""
        z = np.asarray(feature, dtype=float)
        gs, gz = self._grid_s, self._grid_z
        if not self._increasing:
            gs, gz = gs[::-1], gz[::-1]
        s = np.interp(z, gz, gs)
        lo_z, hi_z = gz[0], gz[-1]
        lo_s, hi_s = gs[0], gs[-1]
        slope_lo = self._lo_slope if self._increasing else self._hi_slope
        slope_hi = self._hi_slope if self._increasing else self._lo_slope
        s = np.where(z < lo_z, lo_s + (z - lo_z) / slope_lo, s)
        s = np.where(z > hi_z, hi_s + (z - hi_z) / slope_hi, s)
        return s

    # scalar versions for the filter's once-per-update values: plain floats, no array overhead
    def invert_one(self, feature: float) -> float:
        """:meth:`invert` of one feature value."""
        z = float(feature)
        gs, gz = self._grid_s, self._grid_z
        increasing = self._increasing
        lo_z, hi_z = (gz[0], gz[-1]) if increasing else (gz[-1], gz[0])
        if z < lo_z:
            return float(gs[0] if increasing else gs[-1]) + (z - lo_z) / (
                self._lo_slope if increasing else self._hi_slope)
        if z > hi_z:
            return float(gs[-1] if increasing else gs[0]) + (z - hi_z) / (
                self._hi_slope if increasing else self._lo_slope)
        if not increasing:
            gs, gz = gs[::-1], gz[::-1]
        return float(np.interp(z, gz, gs))

    def severity_noise(self, severity: float) -> float:
        """Measurement noise in severity units at one severity, sigma(s) / |dh/ds| (>= 0)."""
        s = float(severity)
        lo, hi = self.severity_range
        if s > hi:
            slope = self._hi_slope
        elif s < lo:
            slope = self._lo_slope
        else:
            c = self.coefficients
            slope = 0.0
            for j in range(len(c) - 1, 0, -1):
                slope = slope * s + j * c[j]
        sigma = self.noise_std + self.noise_slope * min(max(s, lo), hi)
        return sigma / max(abs(slope), 1e-12)

    def log_likelihood(self, feature: float, severity: NDArray[np.float64]) -> NDArray[np.float64]:
        """log p(feature | severity) up to an additive constant, shape of ``severity``."""
        if self.noise_slope == 0.0:
            r = (feature - self.predict(severity)) / self.noise_std
            return -0.5 * r * r
        sigma = self.noise_at(severity)
        r = (feature - self.predict(severity)) / sigma
        return -0.5 * r * r - np.log(sigma / self.noise_std)

    # -- persistence ------------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        return {
            "version": _VERSION,
            "kind": "polynomial_gaussian",
            "coefficients": list(self.coefficients),
            "noise_std": self.noise_std,
            "noise_slope": self.noise_slope,
            "severity_range": list(self.severity_range),
        }

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), sort_keys=True)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> MeasurementModel:
        if (data.get("version") not in _READABLE_VERSIONS
                or data.get("kind") != "polynomial_gaussian"):
            raise ValueError(
                f"unsupported measurement model {data.get('kind')!r} v{data.get('version')!r}"
            )
        return cls(
            tuple(data["coefficients"]),
            float(data["noise_std"]),
            (float(data["severity_range"][0]), float(data["severity_range"][1])),
            float(data.get("noise_slope", 0.0)),
        )

    @classmethod
    def from_json(cls, text: str) -> MeasurementModel:
        return cls.from_dict(json.loads(text))


def _fit_linear_noise(s: NDArray[np.float64], resid: NDArray[np.float64],
                      sd: float) -> tuple[float, float]:
    """Maximum-likelihood (sigma_0, slope) of N(0, (sigma_0 + slope s)^2) residuals, with
    sigma_0 > 0 and slope >= 0; solved in units of the constant fit's ``sd`` (features span
    1e-6 m to 1), from the constant fit (sd, 0), which it falls back to."""
    u2 = (resid / sd) ** 2

    def nll(p: NDArray[np.float64]) -> float:
        sigma = p[0] + p[1] * s
        return float(np.sum(np.log(sigma) + 0.5 * u2 / (sigma * sigma)))

    start = np.array([1.0, 0.0])
    res = minimize(nll, start, method="L-BFGS-B", bounds=[(1e-3, None), (0.0, None)])
    if not np.all(np.isfinite(res.x)) or nll(res.x) >= nll(start):
        return sd, 0.0
    return float(res.x[0]) * sd, float(res.x[1]) * sd
