"""Healthy baselines of the features, normalised for operating conditions.

Time base: one sample per flight (the per-flight feature value of :mod:`server.phm.features`).

For each of the 20 aircraft features a linear model of the healthy flight value on the
operating conditions of its actuator (ground and mean ambient temperature [degC], rms expected
aerodynamic load [N], rms motor speed [rad/s], and for selected features the winding
temperature estimated from the still-hold resistance [degC]) is fitted on the healthy flights of
a design campaign (ridge regression on standardised covariates, then one refit without gross
outliers). The residual scale is a robust standard deviation (1.4826 x MAD). A flight's
*standardised residual* ``z = (value - expected(conditions)) / scale`` is what detection uses,
so that hot and cold aircraft, heavy and light flights share one healthy distribution.

The condition coefficients are learned **within units** (fixed effects): each actuator's
flights are centred on their own means before the fit, so only how one unit's value moves with
its conditions sets a slope; the intercept is the fleet's mean. Production tolerances give every
unit its own offset, up to eight times the flight scatter (``F_MTWEAR``, ``F_DMD``:
docs/TUNING.md, Detection), and a pooled fit reads any chance correlation of those offsets
with the bases' climates as a temperature slope: on the protocol's design campaign the pooled
fit missed a winglet drive's ``F_MTWEAR`` temperature slope by about 0.045 z per K, so a
unit whose reference was learned in January stood 4 flight-scatter units off by June
(docs/TUNING.md, Baselines). A unit's own offset is the detector's business
(:mod:`server.phm.detection`).

A flight value resting on fewer than ``min_evidence`` (25 %) of the median number of valid
windows of the healthy design flights gets no residual (NaN): its sampling noise is at least
twice the usual (variance ~ 1 / windows), and such flights carried most of the far healthy
residuals of ``F_SE`` and ``F_BDO`` on the design campaign (docs/TUNING.md, Baselines).

Each baseline keeps the range of its conditions over the healthy flights it was fitted on; a
flight far outside it (:meth:`FleetBaseline.outside_design`, ``design_margin``) is one the
baseline would extrapolate on, and the chain sets those features aside with a finding.

The tuned values are the defaults of :class:`BaselineConfig`. Scikit-learn manner:
``__init__`` stores hyper-parameters, ``fit`` returns ``self``, learned attributes end in ``_``.
Persisted as JSON (``to_dict`` / ``from_dict``), never pickle.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from .features import AIRCRAFT_FEATURES, CONDITION_NAMES, FlightFeatures

__all__ = [
    "BASELINE_FORMAT",
    "BASELINE_DEFAULTS",
    "BaselineConfig",
    "DEFAULT_COVARIATES",
    "LinearBaseline",
    "FleetBaseline",
    "OutsideDesign",
    "feature_position",
]

BASELINE_FORMAT = "ema-baseline/1"


@dataclass(frozen=True)
class BaselineConfig:
    """Hyper-parameters of the healthy baselines; the defaults are the tuned values
    (docs/TUNING.md, Baselines). A fitted baseline stores its values in its document.

    Attributes
    ----------
    covariates:
        Operating conditions every feature is regressed on [degC, degC, N, rad/s]: ground and
        mean ambient temperature, rms expected aerodynamic load, rms motor speed; they move
        the healthy value of the features from flight to flight.
    winding_temp_features:
        Generic features that also get the estimated winding temperature [degC] as a
        covariate: their physics depends on the magnet/winding temperature itself.
    drag_weight_features:
        Generic features that also get ``mtel_drag_weight_per_nm`` [1/(N m)] as a covariate
        (:func:`server.phm.features.drag_weight`): a winglet drive's friction ratio carries
        its attached standby's drag over the hinge load, so it falls as the load grows (the
        test station's load scale x0.5-x2 moved a winglet drive's ``F_MTEL`` by -1.8 flight
        scatter units per e-fold of load on the shipped model's design; the wingtip's +0.2).
    ridge:
        L2 penalty on the standardised coefficients [flights' worth]: a light one, so that
        correlated or constant conditions still give a solvable fit (first-cut value).
    outlier_k:
        Residuals beyond this many robust scales are dropped before the one refit [robust
        sd]: only gross outliers (first-cut value).
    min_evidence:
        Fraction of the healthy median number of valid windows a flight value needs to get a
        residual [-]: below a quarter its sampling noise is at least twice the usual.
    within_units:
        Learn the condition slopes within units when the fit is told each flight's unit (the
        module docstring); False pools every flight (the earlier fit, kept to compare).
    log_features:
        Generic features modelled on the log of their value: ratios of a noise-driven spread
        to a mean (``F_BDO`` the phase voltages' imbalance, ``F_SE`` the flux's 1/rev
        modulation) are positive and right-skewed on healthy flights (values 0.0017-0.0095
        and single flights at 0.025 on one long design life), so a normal band on the value
        itself takes their ordinary upper tail for a fault; on the log scale that tail is
        symmetric. A fault multiplies them, which the log keeps.
    design_margin:
        How far beyond the healthy design flights' range of a condition a flight may be and
        still be judged, as a fraction of that range [-]: a linear baseline extrapolated far
        past what it was fitted on says nothing about the unit, so such a flight's features
        are not judged (a finding, not an alarm). A quarter (first-cut value, not tuned):
        the shipped design's ground temperatures span -35..54 degC (its bases' seasons and
        the station's +-30 K), so a flight below about -57 or above 76 degC is out, and one
        whose cruise air (design -55..17 degC) is past 35.
    """

    covariates: tuple[str, ...] = ("temp_ground_c", "temp_mean_c", "load_rms_n",
                                   "speed_rms_rad_s")
    winding_temp_features: tuple[str, ...] = ("F_DMD", "F_MTEL")
    drag_weight_features: tuple[str, ...] = ("F_MTEL",)
    ridge: float = 1.0
    outlier_k: float = 6.0
    min_evidence: float = 0.25
    within_units: bool = True
    log_features: tuple[str, ...] = ("F_SE", "F_BDO")
    design_margin: float = 0.25


#: the tuned baselines (``FleetBaseline()``)
BASELINE_DEFAULTS = BaselineConfig()
DEFAULT_COVARIATES: tuple[str, ...] = BASELINE_DEFAULTS.covariates


@dataclass
class OutsideDesign:
    """A flight's condition far outside what the healthy design flights had: not a fault, a
    flight the baseline cannot judge (its ``features`` are set aside)."""

    position: str
    condition: str
    value: float
    low: float  # the design flights' range of the condition
    high: float
    features: list[str]

    def to_dict(self) -> dict[str, Any]:
        return {"condition": self.condition, "value": self.value, "low": self.low,
                "high": self.high, "features": list(self.features)}


def feature_position(name: str) -> str:
    """Position key of an aircraft feature name (``"WL1.F_TTS"`` -> ``"WL1"``)."""
    return name.split(".", 1)[0]


def _robust_scale(r: np.ndarray) -> float:
    r = r[np.isfinite(r)]
    if r.size < 2:
        return float("nan")
    mad = float(np.median(np.abs(r - np.median(r))))
    s = 1.4826 * mad
    if s <= 0:
        s = float(np.std(r))
    return s


class LinearBaseline:
    """Healthy value of one feature as a linear function of the operating conditions.

    Parameters
    ----------
    covariates : names of the condition columns, in the order of ``C``.
    ridge : L2 penalty on the standardised coefficients (number of flights' worth).
    outlier_k : residuals beyond ``outlier_k`` robust scales are dropped before the refit.
    """

    def __init__(self, covariates: Sequence[str] = BASELINE_DEFAULTS.covariates, *,
                 ridge: float = BASELINE_DEFAULTS.ridge,
                 outlier_k: float = BASELINE_DEFAULTS.outlier_k) -> None:
        self.covariates = tuple(covariates)
        self.ridge = ridge
        self.outlier_k = outlier_k

    # -- fitting ------------------------------------------------------------------------------
    def _prep(self, C: np.ndarray) -> np.ndarray:
        C = np.asarray(C, dtype=np.float64).reshape(-1, len(self.covariates))
        C = np.where(np.isfinite(C), C, self.cov_mean_[np.newaxis, :])
        return (C - self.cov_mean_) / self.cov_scale_

    def fit(self, C: np.ndarray, y: np.ndarray, units: Sequence[str] | None = None
            ) -> LinearBaseline:
        """Fit on healthy flights: ``C`` (n_flights, n_covariates), ``y`` (n_flights,).

        ``units`` (one label per flight, e.g. the aircraft's tail for a position's feature):
        the slopes come from the variation within each unit, the intercept is the mean over
        all flights (module docstring); None: one pooled fit, as if every flight were one
        unit's."""
        C = np.asarray(C, dtype=np.float64).reshape(-1, len(self.covariates))
        y = np.asarray(y, dtype=np.float64)
        keep = np.isfinite(y)
        groups = (np.zeros(y.size, dtype=np.int64) if units is None
                  else np.unique(np.asarray(units, dtype=str), return_inverse=True)[1])
        if groups.size != y.size:
            raise ValueError("units must give one label per flight")
        C, y, groups = C[keep], y[keep], groups[keep]
        if y.size < 3:
            raise ValueError("need at least three healthy flights with a finite value")
        with np.errstate(invalid="ignore"):
            mean = np.nanmean(np.where(np.isfinite(C), C, np.nan), axis=0)
            scale = np.nanstd(np.where(np.isfinite(C), C, np.nan), axis=0)
        mean = np.where(np.isfinite(mean), mean, 0.0)
        scale = np.where(np.isfinite(scale) & (scale > 1e-12), scale, 1.0)
        self.cov_mean_, self.cov_scale_ = mean, scale
        with np.errstate(invalid="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # an all-NaN column: no range
            self.cov_range_ = np.column_stack([np.nanmin(C, axis=0), np.nanmax(C, axis=0)]
                                              ) if C.size else np.full((len(mean), 2), np.nan)
        X = self._prep(C)
        w = np.ones(y.size, dtype=bool)
        for _ in range(2):
            self._solve(X[w], y[w], groups[w])
            r = y - self._raw_predict(X)
            s = _robust_scale(r[w])
            if not np.isfinite(s) or s <= 0:
                break
            w_new = np.abs(r - np.median(r[w])) <= self.outlier_k * s
            if w_new.sum() < 3 or (w_new == w).all():
                break
            w = w_new
        r = y - self._raw_predict(X)
        self.scale_ = max(_robust_scale(r[w]), 1e-12 * max(1.0, float(np.abs(y).max())))
        self.residual_std_ = float(np.std(r[w]))
        self.n_samples_ = int(y.size)
        return self

    def _solve(self, X: np.ndarray, y: np.ndarray, groups: np.ndarray) -> None:
        """Ridge slopes on the deviations from each group's means; intercept from the overall
        means (one group: the ordinary pooled ridge fit)."""
        k = X.shape[1]
        Xc = X - _group_means(X, groups)
        yc = y - _group_means(y[:, np.newaxis], groups)[:, 0]
        A = Xc.T @ Xc + self.ridge * np.eye(k)
        coef = np.linalg.solve(A, Xc.T @ yc) if k else np.zeros(0)
        self.coef_ = coef
        self.intercept_ = float(y.mean() - X.mean(axis=0) @ coef)

    def _raw_predict(self, X: np.ndarray) -> np.ndarray:
        return self.intercept_ + X @ self.coef_

    def _check(self) -> None:
        if not hasattr(self, "coef_"):
            raise RuntimeError("LinearBaseline is not fitted")

    # -- use ----------------------------------------------------------------------------------
    def predict(self, C: np.ndarray) -> np.ndarray:
        """Expected healthy value for conditions ``C`` (n, n_covariates) -> (n,)."""
        self._check()
        return self._raw_predict(self._prep(C))

    def zscore(self, C: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Standardised residual ``(y - predict(C)) / scale_`` (n,)."""
        return (np.asarray(y, dtype=np.float64) - self.predict(C)) / self.scale_

    def outside(self, c: np.ndarray, margin: float) -> list[int]:
        """Indices of the covariates of one flight ``c`` (n_covariates,) beyond the fitted
        flights' range widened by ``margin`` times it each side (none without a range: a
        document written before ranges were kept; none for a condition the fit never saw
        vary)."""
        rng = getattr(self, "cov_range_", None)
        if rng is None:
            return []
        span = rng[:, 1] - rng[:, 0]
        with np.errstate(invalid="ignore"):
            out = (c < rng[:, 0] - margin * span) | (c > rng[:, 1] + margin * span)
        # a condition the design never varied taught no slope, so nothing extrapolates on it
        return [int(i) for i in np.flatnonzero(out & (span > 0))]

    def to_dict(self) -> dict[str, Any]:
        self._check()
        return {"covariates": list(self.covariates), "ridge": self.ridge,
                "outlier_k": self.outlier_k, "cov_mean": self.cov_mean_.tolist(),
                "cov_scale": self.cov_scale_.tolist(), "coef": self.coef_.tolist(),
                "intercept": self.intercept_, "scale": self.scale_,
                "residual_std": self.residual_std_, "n_samples": self.n_samples_,
                **({"cov_range": [[float(v) if np.isfinite(v) else None for v in row]
                                  for row in self.cov_range_]}
                   if getattr(self, "cov_range_", None) is not None else {})}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> LinearBaseline:
        b = cls(d["covariates"], ridge=float(d["ridge"]), outlier_k=float(d["outlier_k"]))
        b.cov_mean_ = np.asarray(d["cov_mean"], dtype=np.float64)
        b.cov_scale_ = np.asarray(d["cov_scale"], dtype=np.float64)
        b.coef_ = np.asarray(d["coef"], dtype=np.float64)
        b.intercept_ = float(d["intercept"])
        b.scale_ = float(d["scale"])
        b.residual_std_ = float(d["residual_std"])
        b.n_samples_ = int(d["n_samples"])
        if d.get("cov_range") is not None:
            b.cov_range_ = np.array([[np.nan if v is None else v for v in row]
                                     for row in d["cov_range"]], dtype=np.float64).reshape(-1, 2)
        return b


def _group_means(X: np.ndarray, groups: np.ndarray) -> np.ndarray:
    """Each row's group mean of ``X`` (n, k), by integer group labels (n,)."""
    counts = np.bincount(groups)
    sums = np.zeros((counts.size, X.shape[1]))
    np.add.at(sums, groups, X)
    return (sums / np.maximum(counts, 1)[:, np.newaxis])[groups]


def _covariates_for(name: str, base: Sequence[str]) -> tuple[str, ...]:
    feat = name.split(".", 1)[1]
    extra = ((("temp_winding_est_c",) if feat in BASELINE_DEFAULTS.winding_temp_features
              else ())
             + (("mtel_drag_weight_per_nm",) if feat in BASELINE_DEFAULTS.drag_weight_features
                else ()))
    return tuple(base) + tuple(c for c in extra if c not in base)


class FleetBaseline:
    """One :class:`LinearBaseline` per aircraft feature (20), fitted on healthy flights.

    Parameters
    ----------
    covariates : condition names used by every feature (``CONDITION_NAMES`` subset);
        ``F_DMD`` and ``F_MTEL`` also use the estimated winding temperature.
    ridge, outlier_k : passed to each :class:`LinearBaseline`.
    min_evidence : fraction of the healthy median number of valid windows a flight value
        needs to get a residual (module docstring).
    """

    def __init__(self, covariates: Sequence[str] = BASELINE_DEFAULTS.covariates, *,
                 ridge: float = BASELINE_DEFAULTS.ridge,
                 outlier_k: float = BASELINE_DEFAULTS.outlier_k,
                 min_evidence: float = BASELINE_DEFAULTS.min_evidence,
                 within_units: bool = BASELINE_DEFAULTS.within_units,
                 log_features: Sequence[str] = BASELINE_DEFAULTS.log_features,
                 design_margin: float = BASELINE_DEFAULTS.design_margin) -> None:
        unknown = set(covariates) - set(CONDITION_NAMES)
        if unknown:
            raise ValueError(f"unknown covariates {sorted(unknown)}")
        self.covariates = tuple(covariates)
        self.ridge = ridge
        self.outlier_k = outlier_k
        self.min_evidence = float(min_evidence)
        self.within_units = bool(within_units)
        self.log_features = tuple(log_features)
        self.design_margin = float(design_margin)

    def _values(self, flights: Sequence[FlightFeatures], name: str) -> np.ndarray:
        """Feature values (their log for ``log_features``), NaN where the flight has too
        little evidence or a log feature no positive value."""
        need = self.min_valid_.get(name, 0.0) if hasattr(self, "min_valid_") else 0.0
        v = np.array([f.summaries[name].value if f.summaries[name].n_valid >= need
                      else np.nan for f in flights], dtype=np.float64)
        if name.split(".", 1)[1] in self.log_features:
            with np.errstate(invalid="ignore", divide="ignore"):
                v = np.where(v > 0, np.log(np.where(v > 0, v, 1.0)), np.nan)
        return v

    @staticmethod
    def _cond_matrix(flights: Sequence[FlightFeatures], name: str,
                     cov: Sequence[str]) -> np.ndarray:
        pos = feature_position(name)
        return np.array([[f.conditions[pos].get(c, np.nan) for c in cov] for f in flights],
                        dtype=np.float64).reshape(len(flights), len(cov))

    def fit(self, flights: Sequence[FlightFeatures],
            units: Sequence[str] | None = None) -> FleetBaseline:
        """Fit every feature's baseline on healthy ``flights``; ``units`` labels each flight
        with its aircraft (every feature belongs to one position, so the aircraft names the
        unit): the slopes are then learned within units (module docstring)."""
        if len(flights) < 3:
            raise ValueError("need at least three healthy flights")
        if units is not None and len(units) != len(flights):
            raise ValueError("units must give one label per flight")
        if not self.within_units:
            units = None
        self.models_: dict[str, LinearBaseline] = {}
        self.min_valid_: dict[str, float] = {}
        for name in AIRCRAFT_FEATURES:
            n_valid = np.array([f.summaries[name].n_valid for f in flights
                                if np.isfinite(f.summaries[name].value)], dtype=np.float64)
            self.min_valid_[name] = (self.min_evidence * float(np.median(n_valid))
                                     if n_valid.size else 0.0)
            cov = _covariates_for(name, self.covariates)
            y = self._values(flights, name)
            C = self._cond_matrix(flights, name, cov)
            self.models_[name] = LinearBaseline(cov, ridge=self.ridge,
                                                outlier_k=self.outlier_k).fit(C, y, units)
        self.feature_names_ = AIRCRAFT_FEATURES
        self.n_flights_ = len(flights)
        return self

    def _check(self) -> None:
        if not hasattr(self, "models_"):
            raise RuntimeError("FleetBaseline is not fitted")

    def zscores(self, flight: FlightFeatures) -> dict[str, float]:
        """Standardised residual of every feature of one flight (NaN where no valid window)."""
        self._check()
        out: dict[str, float] = {}
        for name, m in self.models_.items():
            C = self._cond_matrix([flight], name, m.covariates)
            out[name] = float(m.zscore(C, self._values([flight], name))[0])
        return out

    def outside_design(self, flight: FlightFeatures) -> list[OutsideDesign]:
        """The flight's conditions far outside the healthy design flights' (``design_margin``),
        one per position and condition, each with the features that model it."""
        self._check()
        found: dict[tuple[str, str], OutsideDesign] = {}
        for name, m in self.models_.items():
            c = self._cond_matrix([flight], name, m.covariates)[0]
            for i in m.outside(c, self.design_margin):
                key = (feature_position(name), m.covariates[i])
                if key not in found:
                    lo, hi = m.cov_range_[i]
                    found[key] = OutsideDesign(*key, float(c[i]), float(lo), float(hi), [])
                found[key].features.append(name)
        return list(found.values())

    def evidence_weights(self, flight: FlightFeatures) -> dict[str, float]:
        """Per feature of a flight, the healthy design flights' median number of valid windows
        over this flight's (at least one): how much more a noise-driven error weighs on it
        (a 60 s recording against a design of 120 s ones: about 2; 1 where the design saw no
        value of the feature)."""
        out = {}
        for name, s in flight.summaries.items():
            typical = self._typical_valid(name)
            out[name] = typical / max(s.n_valid, 1) if typical > 0 else 1.0
        return out

    def evidence_matrix(self, flights: Sequence[FlightFeatures]) -> np.ndarray:
        """(n_flights, 20) :meth:`evidence_weights` in ``AIRCRAFT_FEATURES`` order."""
        self._check()
        typical = np.array([self._typical_valid(n) for n in AIRCRAFT_FEATURES])
        n_valid = np.array([[f.summaries[n].n_valid for n in AIRCRAFT_FEATURES]
                            for f in flights], dtype=np.float64).reshape(-1, typical.size)
        return np.where(typical > 0, typical / np.maximum(n_valid, 1.0), 1.0)

    def _typical_valid(self, name: str) -> float:
        """The healthy design flights' median number of valid windows of a feature (0: not
        known)."""
        need = self.min_valid_.get(name, 0.0)
        return need / self.min_evidence if self.min_evidence > 0 else 0.0

    def to_physical(self, z: Mapping[str, float]) -> dict[str, float]:
        """Standardised residuals (or offsets) back in each feature's physical unit,
        ``value - expected(conditions)`` (of the log value for ``log_features``): comparable
        across positions, unlike ``zscores``."""
        self._check()
        return {name: v * self.models_[name].scale_ for name, v in z.items()
                if name in self.models_}

    def zscore_matrix(self, flights: Sequence[FlightFeatures]) -> np.ndarray:
        """(n_flights, 20) standardised residuals in ``AIRCRAFT_FEATURES`` order."""
        self._check()
        cols = []
        for name in AIRCRAFT_FEATURES:
            m = self.models_[name]
            C = self._cond_matrix(flights, name, m.covariates)
            cols.append(m.zscore(C, self._values(flights, name)))
        return np.column_stack(cols) if cols else np.zeros((len(flights), 0))

    def to_dict(self) -> dict[str, Any]:
        self._check()
        return {"format": BASELINE_FORMAT, "covariates": list(self.covariates),
                "ridge": self.ridge, "outlier_k": self.outlier_k, "n_flights": self.n_flights_,
                "min_evidence": self.min_evidence, "min_valid": dict(self.min_valid_),
                "within_units": self.within_units, "log_features": list(self.log_features),
                "design_margin": self.design_margin,
                "models": {k: m.to_dict() for k, m in self.models_.items()}}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> FleetBaseline:
        if d.get("format") != BASELINE_FORMAT:
            raise ValueError(f"not a {BASELINE_FORMAT} document")
        # a document without these keys pooled its fit and modelled every value as it is
        b = cls(d["covariates"], ridge=float(d["ridge"]), outlier_k=float(d["outlier_k"]),
                min_evidence=float(d.get("min_evidence", 0.0)),
                within_units=bool(d.get("within_units", False)),
                log_features=tuple(d.get("log_features", ())),
                design_margin=float(d.get("design_margin", BASELINE_DEFAULTS.design_margin)))
        b.min_valid_ = {k: float(v) for k, v in (d.get("min_valid") or {}).items()}
        b.models_ = {k: LinearBaseline.from_dict(v) for k, v in d["models"].items()}
        b.feature_names_ = tuple(b.models_)
        b.n_flights_ = int(d["n_flights"])
        return b
