"""Long-term prediction: propagate every particle to the failure threshold -> RUL distribution.

Conventions
-----------
- RUL is in flights, counted from the flight of the last update (``flight_index``); fractional
  values come from linear interpolation of the threshold crossing inside a prediction step.
- A particle that has not crossed the threshold within ``max_horizon_flights`` has RUL = +inf
  ("beyond horizon"); quantiles falling among those are +inf (serialised as ``null``).
- Flight hours: when the mean flight duration is known, ``rul_hours`` = RUL [flight] * mean hours
  per flight.
- The propagation is a compiled loop (numba) over future prediction steps and particles. The
  step is a whole number of flights chosen so that about ``prediction_steps`` steps reach the
  expected failure time; it doubles every ``prediction_steps`` steps so that slow or stalled
  particles cost a bounded number of steps.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numba import njit
from numpy.typing import NDArray

from .config import PrognoserConfig
from .constants import CONSTANTS
from .degradation import growth_rate

__all__ = ["RulDistribution", "most_probable_rul", "propagate_to_threshold", "summarise_rul",
           "weighted_quantiles"]

_VERSION = 1


@dataclass(frozen=True)
class RulDistribution:
    """RUL distribution at one prediction time.

    Attributes
    ----------
    flight_index:
        Flight of the last measurement used [flight] (None before any update).
    quantiles:
        {level: RUL [flight]} for the configured levels (default 5, 25, 50, 75, 95 %).
    mean:
        Weighted mean of the finite RULs [flight] (nan if none is finite).
    p_fail_within:
        {horizon [flight]: probability of failure within that many flights} [-].
    p_beyond_horizon:
        Probability mass that did not fail within ``max_horizon_flights`` [-].
    histogram_edges, histogram_mass:
        Histogram of the finite RULs: edges [flight] (bins + 1,), probability mass per bin (bins,).
    severity_mean, severity_std:
        Weighted mean and standard deviation of the current severity [-].
    most_probable:
        Mode of the RUL density [flight] (the paper's "most probable RUL estimate"): the peak
        of a weighted Gaussian kernel density of the finite RULs (:func:`most_probable_rul`);
        +inf when most of the mass lies beyond the horizon.
    hours_per_flight:
        Mean flight duration [h] when known, else None.
    samples, weights:
        Particle RULs [flight] and their normalised weights (kept in memory; optional in JSON).
    rate_ratio:
        The filter's rate over its prior's centre (the RLS estimate's), the
        calibration layer's group key; nan when the filter does not carry its rate.
    hypothesis:
        With a bank of rate hypotheses (:mod:`.hypotheses`): the leading one's name, its spans
        in words and its weight, and every hypothesis's weight by name; else None.
    adjustment:
        What moved the band from the particles' quantiles (the online guard's widening, the
        calibration layer's group and margins, :mod:`.calibration`), or None: the quantiles
        are the particles' own (``samples`` and the histogram always are).
    """

    flight_index: int | None
    quantiles: dict[float, float]
    mean: float
    p_fail_within: dict[int, float]
    p_beyond_horizon: float
    histogram_edges: NDArray[np.float64]
    histogram_mass: NDArray[np.float64]
    severity_mean: float
    severity_std: float
    most_probable: float = math.nan
    hours_per_flight: float | None = None
    samples: NDArray[np.float64] = field(default_factory=lambda: np.empty(0), repr=False)
    weights: NDArray[np.float64] = field(default_factory=lambda: np.empty(0), repr=False)
    rate_ratio: float = math.nan
    adjustment: dict[str, Any] | None = None
    hypothesis: dict[str, Any] | None = None

    @property
    def median(self) -> float:
        """Median RUL [flight] (the 0.5 quantile, computed even if not configured)."""
        if 0.5 in self.quantiles:
            return self.quantiles[0.5]
        return float(weighted_quantiles(self.samples, self.weights, (0.5,))[0])

    def quantile(self, level: float) -> float:
        """RUL [flight] at ``level``, a fraction in (0, 1): a configured level's stored value,
        any other computed from the particles (see :meth:`percentile` for percent)."""
        q = float(level)
        if not 0.0 < q < 1.0:
            raise ValueError(f"level must be a fraction in (0, 1), got {level!r} "
                             "(percentile() takes percent)")
        if q in self.quantiles:
            return self.quantiles[q]
        if self.samples.size == 0:
            raise ValueError(f"level {q} is not among the stored quantiles "
                             f"{sorted(self.quantiles)} and the particles were not kept")
        return float(weighted_quantiles(self.samples, self.weights, (q,))[0])

    def percentile(self, percent: float) -> float:
        """RUL [flight] at ``percent`` in (0, 100), e.g. ``percentile(5)``."""
        p = float(percent)
        if not 0.0 < p < 100.0:
            raise ValueError(f"percent must lie in (0, 100), got {percent!r}")
        return self.quantile(round(p / 100.0, 12))

    @property
    def failure_flight_median(self) -> float:
        """Median predicted failure flight [flight] = flight_index + median RUL."""
        return float((self.flight_index or 0) + self.median)

    def quantiles_hours(self) -> dict[float, float] | None:
        """Quantiles in flight hours, or None when the flight duration is unknown."""
        if self.hours_per_flight is None:
            return None
        return {q: v * self.hours_per_flight for q, v in self.quantiles.items()}

    def to_dict(self, *, include_samples: bool = False) -> dict[str, Any]:
        data: dict[str, Any] = {
            "version": _VERSION,
            "kind": "rul_distribution",
            "flight_index": self.flight_index,
            "quantiles": [[q, _finite_or_none(v)] for q, v in self.quantiles.items()],
            "mean": _finite_or_none(self.mean),
            "p_fail_within": [[h, p] for h, p in self.p_fail_within.items()],
            "p_beyond_horizon": self.p_beyond_horizon,
            "histogram_edges": self.histogram_edges.tolist(),
            "histogram_mass": self.histogram_mass.tolist(),
            "severity_mean": self.severity_mean,
            "severity_std": self.severity_std,
            "most_probable": _finite_or_none(self.most_probable),
            "hours_per_flight": self.hours_per_flight,
        }
        if math.isfinite(self.rate_ratio):  # absent otherwise: documents read as before
            data["rate_ratio"] = self.rate_ratio
        if self.adjustment is not None:
            data["adjustment"] = _json_safe(self.adjustment)
        if self.hypothesis is not None:
            data["hypothesis"] = _json_safe(self.hypothesis)
        if include_samples:
            data["samples"] = [_finite_or_none(v) for v in self.samples.tolist()]
            data["weights"] = self.weights.tolist()
        return data

    def to_json(self, *, include_samples: bool = False) -> str:
        return json.dumps(self.to_dict(include_samples=include_samples), sort_keys=True)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> RulDistribution:
        if data.get("version") != _VERSION or data.get("kind") != "rul_distribution":
            raise ValueError("not a version-1 rul_distribution")
        samples = data.get("samples")
        return cls(
            flight_index=data["flight_index"],
            quantiles={float(q): _none_to_inf(v) for q, v in data["quantiles"]},
            mean=math.nan if data["mean"] is None else float(data["mean"]),
            p_fail_within={int(h): float(p) for h, p in data["p_fail_within"]},
            p_beyond_horizon=float(data["p_beyond_horizon"]),
            histogram_edges=np.asarray(data["histogram_edges"], dtype=float),
            histogram_mass=np.asarray(data["histogram_mass"], dtype=float),
            severity_mean=float(data["severity_mean"]),
            severity_std=float(data["severity_std"]),
            # absent from documents written before it existed; null: beyond the horizon
            most_probable=(math.nan if "most_probable" not in data
                           else _none_to_inf(data["most_probable"])),
            hours_per_flight=data.get("hours_per_flight"),
            samples=np.empty(0)
            if samples is None
            else np.array([_none_to_inf(v) for v in samples]),
            weights=np.asarray(data.get("weights") or [], dtype=float),
            rate_ratio=float(data.get("rate_ratio", math.nan)),
            adjustment=data.get("adjustment"),
            hypothesis=data.get("hypothesis"),
        )

    @classmethod
    def from_json(cls, text: str) -> RulDistribution:
        return cls.from_dict(json.loads(text))


def _finite_or_none(v: float) -> float | None:
    return float(v) if math.isfinite(v) else None


def _none_to_inf(v: float | None) -> float:
    return math.inf if v is None else float(v)


def _json_safe(obj: Any) -> Any:
    """Float keys as strings and non-finite floats as None, for a JSON document."""
    if isinstance(obj, dict):
        return {str(k): _json_safe(v) for k, v in obj.items()}
    if isinstance(obj, float):
        return _finite_or_none(obj)
    return obj


def weighted_quantiles(
    values: NDArray[np.float64], weights: NDArray[np.float64], levels: tuple[float, ...]
) -> NDArray[np.float64]:
    """Inverted-CDF weighted quantiles (no interpolation, so +inf values are handled exactly)."""
    order = np.argsort(values, kind="stable")
    cdf = np.cumsum(weights[order])
    idx = np.searchsorted(cdf, np.asarray(levels) * cdf[-1], side="left")
    return values[order][np.minimum(idx, values.size - 1)]


def most_probable_rul(rul: NDArray[np.float64], weights: NDArray[np.float64]) -> float:
    """Mode of the weighted RUL density [flight]; +inf when the finite RULs hold less than half
    the mass (the most probable outcome is then "beyond the horizon").

    Gaussian kernel density with Silverman's bandwidth, 0.9 min(sd, IQR / 1.34) n_eff^(-1/5)
    (n_eff = 1 / sum w^2, the weights normalised over the finite RULs), evaluated on a
    ``CONSTANTS.mode_grid``-bin histogram convolved with the kernel (binned KDE: one small
    convolution instead of N x grid exponentials). The paper's point estimate; the median of a
    right-skewed RUL distribution lies above its mode.
    """
    finite = np.isfinite(rul)
    mass = float(weights[finite].sum())
    if mass <= 0.5 * float(weights.sum()):
        return math.inf
    r, w = rul[finite], weights[finite] / mass
    lo, hi = float(r.min()), float(r.max())
    if hi - lo <= 1e-9 * max(1.0, hi):
        return lo
    mean = float(np.dot(w, r))
    sd = math.sqrt(max(float(np.dot(w, (r - mean) ** 2)), 0.0))
    q25, q75 = weighted_quantiles(r, w, (0.25, 0.75))
    spread = min(sd, float(q75 - q25) / 1.34) if q75 > q25 else sd
    n_eff = 1.0 / float(np.dot(w, w))
    bandwidth = max(0.9 * spread * n_eff ** -0.2, 1e-9 * max(1.0, hi))
    # the grid reaches 3 bandwidths beyond the samples, so a peak at an end is not clipped
    grid = CONSTANTS.mode_grid
    lo_g, hi_g = max(lo - 3.0 * bandwidth, 0.0), hi + 3.0 * bandwidth
    width = (hi_g - lo_g) / grid
    hist, _ = np.histogram(r, bins=grid, range=(lo_g, hi_g), weights=w)
    half = min(int(math.ceil(4.0 * bandwidth / width)), (grid - 1) // 2)
    x = np.arange(-half, half + 1) * (width / bandwidth)
    density = np.convolve(hist, np.exp(-0.5 * x * x), mode="same")
    return lo_g + (int(np.argmax(density)) + 0.5) * width


def propagate_to_threshold(
    severity: NDArray[np.float64],
    theta: NDArray[np.float64],
    config: PrognoserConfig,
    rng: np.random.Generator,
    *,
    threshold: float = 1.0,
    horizon: float | None = None,
) -> NDArray[np.float64]:
    """Time to threshold [flight] of every particle (shape (N,)), +inf beyond the horizon.

    ``theta`` has shape (p,) or (N, p) (one vector of growth-rate coefficients per particle:
    every law is a polynomial in h here, :meth:`.laws.DegradationLaw.coefficients`). Euler steps of
    ``step`` flights with the prediction's noise ``q sqrt(step)``
    (:attr:`PrognoserConfig.prediction_noise`); crossing time interpolated linearly.
    Time is in the law's clock (flights, or stress units: :mod:`server.phm.season`);
    ``horizon`` defaults to ``config.max_horizon_flights``.
    """
    h = severity.astype(float, copy=True)
    n = h.size
    rul = np.full(n, np.inf)
    failed = h >= threshold
    rul[failed] = 0.0
    n_done = int(failed.sum())
    if n_done == n:
        return rul
    cap = 4.0 * threshold + 1.0  # failed particles are parked here: h < threshold never again
    h[failed] = cap
    # step size from the expected time to failure of the mean particle at its current rate
    h_ref = float(np.mean(h[~failed]))
    theta_ref = theta if theta.ndim == 1 else theta.mean(axis=0)
    rate_ref = float(growth_rate(np.array([h_ref]), theta_ref, config.min_rate)[0])
    horizon = float(config.max_horizon_flights) if horizon is None else float(horizon)
    t_expected = min((threshold - h_ref) / rate_ref, horizon)
    step = max(1, int(math.ceil(t_expected / config.prediction_steps)))
    coefs = np.ascontiguousarray(np.broadcast_to(theta, (n, theta.shape[-1])), dtype=float)
    q = config.prediction_noise
    block = config.prediction_steps
    t = 0.0
    while True:  # blocks of ``block`` Euler steps; the step doubles from one block to the next
        noise = q * rng.standard_normal((block, n))
        t, n_done = _euler_block(h, coefs, config.min_rate, threshold, cap, float(step),
                                 horizon, noise, t, rul, n_done)
        if n_done >= n or t >= horizon:
            return rul
        step *= 2


@njit(cache=True)
def _euler_block(h, coefs, min_rate, threshold, cap, step, horizon, noise, t, rul, n_done):  # type: ignore[no-untyped-def]  # noqa: E501  # numba types it from its arguments
    """Up to ``noise.shape[0]`` Euler steps of ``step`` flights for every particle, in place
    (``h``, ``rul``); returns (t, n_done). The growth rate is the law's polynomial in Horner
    form floored at ``min_rate`` (the same loop for every law: no law code); a particle that
    crosses the threshold gets its interpolated crossing time and is parked at ``cap``.
    Compiled: the loop over steps is the prediction's cost (about 100 steps of 200 particles),
    which numpy paid per call."""
    n, p = coefs.shape
    for i in range(noise.shape[0]):
        if t >= horizon:
            break
        dt = min(step, horizon - t)
        sq = math.sqrt(dt)
        for k in range(n):
            hk = h[k]
            if p > 1:
                rate = coefs[k, p - 1] * hk
                for j in range(p - 2, 0, -1):
                    rate = (rate + coefs[k, j]) * hk
                rate += coefs[k, 0]
            else:
                rate = coefs[k, 0]
            hn = max(rate, min_rate) * dt + hk + sq * noise[i, k]
            if hn >= threshold and hk < threshold:
                rul[k] = t + dt * (threshold - hk) / (hn - hk)
                hn = cap
                n_done += 1
            h[k] = min(max(hn, 0.0), cap)
        if n_done >= n:
            return t, n_done
        t += dt
    return t, n_done


def summarise_rul(
    rul: NDArray[np.float64],
    weights: NDArray[np.float64],
    severity: NDArray[np.float64],
    config: PrognoserConfig,
    *,
    flight_index: int | None,
    hours_per_flight: float | None,
) -> RulDistribution:
    """Quantiles, histogram and probabilities of failure from particle RULs and weights."""
    w = weights / weights.sum()
    finite = np.isfinite(rul)
    levels = config.quantile_levels
    qs = weighted_quantiles(rul, w, levels)
    mass_finite = float(w[finite].sum())
    mean = float(np.dot(w[finite], rul[finite]) / mass_finite) if mass_finite > 0 else math.nan
    p_fail = {hz: float(w[rul <= hz].sum()) for hz in config.pof_horizons_flights}
    if finite.any():
        top = float(rul[finite].max())
        edges = np.linspace(0.0, max(top, 1.0), config.histogram_bins + 1)
        mass, _ = np.histogram(rul[finite], bins=edges, weights=w[finite])
    else:
        edges = np.linspace(0.0, float(config.max_horizon_flights), config.histogram_bins + 1)
        mass = np.zeros(config.histogram_bins)
    sev_mean = float(np.dot(w, severity))
    sev_std = float(np.sqrt(max(np.dot(w, (severity - sev_mean) ** 2), 0.0)))
    return RulDistribution(
        flight_index=flight_index,
        quantiles={lvl: float(v) for lvl, v in zip(levels, qs, strict=True)},
        mean=mean,
        p_fail_within=p_fail,
        p_beyond_horizon=float(min(max(1.0 - mass_finite, 0.0), 1.0)),  # no -4e-16
        histogram_edges=edges,
        histogram_mass=mass.astype(float),
        severity_mean=sev_mean,
        severity_std=sev_std,
        most_probable=most_probable_rul(rul, w),
        hours_per_flight=hours_per_flight,
        samples=rul,
        weights=w,
    )
