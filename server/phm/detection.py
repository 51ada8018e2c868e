"""Fault detection: running feature distributions against their healthy baselines.

Time base: one update per flight, per monitored unit (an actuator ``WL1``/``WL2``/``WT`` with
its six features, or the winglet pair ``WL`` with ``F_REWEAR``). Inputs are the standardised
residuals ``z`` of :class:`server.phm.baselines.FleetBaseline` (dimensionless, N(0, 1) on
healthy flights by construction).

Running distribution and separation confidence
----------------------------------------------
For each feature the state keeps the residuals of the last ``max(windows)`` flights with a
valid value. For each window length ``w`` (default 1, 3 and 8 flights) the running mean of the
last ``n = min(w, available)`` residuals, scaled to unit variance, is ``S_w = sqrt(n) mean(z)``.
On healthy flights ``|S_w|`` stays inside a band ``b_w`` learned on the healthy flights of the
*design* campaign (the largest ``|S_w|`` seen there, never less than ``band_floor``). Because
``S_w`` has unit standard error, the confidence that the running mean lies outside the healthy
band is

    c_w = Phi(|S_w| - b_w),      c = max over w of c_w  in [0, 1],

and the unit alarms when ``c`` of any of its features reaches ``alarm_confidence`` (0.98, the
paper's value), i.e. ``|S_w| >= b_w + 2.05``. The short window reacts within one flight to
step faults (SE, BDO); the long window accumulates evidence of slow drifts. The alarm latches
until maintenance: replacing an actuator gives it a fresh state
(:meth:`DetectionState.reset` does the same in place).

The test is one-sided along each fault's physical direction (``DEFAULT_DIRECTIONS``: F_MTEL
falls, every other feature grows), ``|S_w|`` being replaced by ``direction * S_w``, and one
band serves a generic feature on every position (the largest over the positions).

Everything persists as JSON (``to_dict`` / ``from_dict``), never pickle.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.special import ndtr, ndtri

__all__ = [
    "DETECTOR_FORMAT",
    "DEFAULT_DIRECTIONS",
    "generic_feature",
    "STATE_FORMAT",
    "UNITS",
    "unit_features",
    "DetectionState",
    "DetectionResult",
    "FaultDetector",
    "running_statistics",
]

DETECTOR_FORMAT = "ema-detector/1"
#: physical direction of each generic feature under its fault: +1 grows, -1 falls, 0 either
DEFAULT_DIRECTIONS: dict[str, int] = {"F_TTS": 1, "F_DMD": 1, "F_SE": 1, "F_BDO": 1,
                                      "F_MTEL": -1, "F_MTWEAR": 1, "F_REWEAR": 1}
#: shortest alarm window per generic feature (see FaultDetector, ``min_windows``)
DEFAULT_MIN_WINDOWS: dict[str, int] = {"F_MTEL": 3}
STATE_FORMAT = "ema-detection-state/1"
#: monitored units and the prefix of their feature names
UNITS: tuple[str, ...] = ("WL1", "WL2", "WT", "WL")


def generic_feature(name: str) -> str:
    """``"WL1.F_TTS"`` -> ``"F_TTS"``."""
    return name.split(".", 1)[-1]


def unit_features(unit: str, feature_names: Iterable[str]) -> list[str]:
    """Feature names (``"<unit>.F_*"``) that belong to ``unit``."""
    return [f for f in feature_names if f.split(".", 1)[0] == unit]


def running_statistics(z: np.ndarray, window: int) -> np.ndarray:
    """``S_w`` for every flight of a sequence: (n_flights, n_features) -> same shape.

    NaN residuals (no valid window in that flight) are skipped: the window then reaches further
    back. Before any valid residual the statistic is NaN. Vectorised per feature column.
    """
    z = np.asarray(z, dtype=np.float64)
    if z.ndim == 1:
        z = z[:, np.newaxis]
    out = np.full(z.shape, np.nan)
    for j in range(z.shape[1]):
        col = z[:, j]
        ok = np.flatnonzero(np.isfinite(col))
        if ok.size == 0:
            continue
        v = col[ok]
        cs = np.r_[0.0, np.cumsum(v)]
        k = np.arange(1, v.size + 1)
        lo = np.maximum(k - window, 0)
        n = k - lo
        s = (cs[k] - cs[lo]) / np.sqrt(n)
        full = np.full(col.size, np.nan)
        full[ok] = s
        last = np.maximum.accumulate(np.where(np.isfinite(col), np.arange(col.size), -1))
        held = last >= 0
        full[held] = full[last[held]]
        out[:, j] = full
    return out


@dataclass
class DetectionState:
    """Per-unit state carried from flight to flight (JSON-serialisable)."""

    unit: str
    features: list[str]
    history: dict[str, list[float]] = field(default_factory=dict)  # last residuals, oldest first
    n_flights: int = 0  # flights seen since the last reset
    alarm: bool = False
    alarm_flight: int | None = None  # n_flights count at which the alarm was raised
    alarm_features: list[str] = field(default_factory=list)
    confidence: dict[str, float] = field(default_factory=dict)  # latest, per feature

    @classmethod
    def new(cls, unit: str, features: Iterable[str]) -> DetectionState:
        feats = list(features)
        return cls(unit=unit, features=feats, history={f: [] for f in feats},
                   confidence={f: 0.0 for f in feats})

    def reset(self) -> None:
        """Forget the history and clear the alarm (after maintenance)."""
        self.history = {f: [] for f in self.features}
        self.n_flights = 0
        self.alarm = False
        self.alarm_flight = None
        self.alarm_features = []
        self.confidence = {f: 0.0 for f in self.features}

    def to_dict(self) -> dict[str, Any]:
        return {"format": STATE_FORMAT, "unit": self.unit, "features": list(self.features),
                "history": {k: [float(x) for x in v] for k, v in self.history.items()},
                "n_flights": self.n_flights, "alarm": self.alarm,
                "alarm_flight": self.alarm_flight, "alarm_features": list(self.alarm_features),
                "confidence": {k: float(v) for k, v in self.confidence.items()}}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> DetectionState:
        if d.get("format") != STATE_FORMAT:
            raise ValueError(f"not a {STATE_FORMAT} document")
        return cls(unit=str(d["unit"]), features=list(d["features"]),
                   history={k: [float(x) for x in v] for k, v in d["history"].items()},
                   n_flights=int(d["n_flights"]), alarm=bool(d["alarm"]),
                   alarm_flight=None if d["alarm_flight"] is None else int(d["alarm_flight"]),
                   alarm_features=list(d["alarm_features"]),
                   confidence={k: float(v) for k, v in d["confidence"].items()})


@dataclass(frozen=True)
class DetectionResult:
    """Outcome of one flight's update of one unit."""

    confidence: dict[str, float]  # per feature, in [0, 1]
    max_confidence: float
    alarm: bool  # latched alarm state after this flight
    new_alarm: bool  # raised by this flight
    alarm_features: list[str]


class FaultDetector:
    """Separation-confidence detector with bands learned on healthy design flights.

    Parameters
    ----------
    windows : running-window lengths in flights.
    alarm_confidence : confidence at which a unit alarms (0.98).
    band_floor : smallest allowed band ``b_w`` (in standard errors).
    band_margin : extra margin added to the largest healthy ``|S_w|`` (standard errors).
    directions : generic feature -> +1 (the fault makes it grow), -1 (fall) or 0 (either);
        the statistic is ``direction * S_w`` (one-sided test), ``|S_w|`` for 0 / unknown.
    pool_positions : one band per generic feature, the largest over the positions (more
        healthy flights behind each band, same physics on every actuator).
    min_windows : generic feature -> shortest window allowed to raise an alarm (flights of
        evidence). ``F_MTEL`` needs 3: lubricant ageing evolves over hundreds of flights, and
        its feature has heavy-tailed healthy residuals on flights with few cruise moves in one
        direction, so a single flight is never enough evidence.
    """

    def __init__(self, windows: Sequence[int] = (1, 3, 8), *, alarm_confidence: float = 0.98,
                 band_floor: float = 3.0, band_margin: float = 0.0,
                 directions: Mapping[str, int] | None = None,
                 pool_positions: bool = True,
                 min_windows: Mapping[str, int] | None = None) -> None:
        if not windows or min(windows) < 1:
            raise ValueError("windows must be positive flight counts")
        if not 0.5 < alarm_confidence < 1.0:
            raise ValueError("alarm_confidence must lie in (0.5, 1)")
        self.windows = tuple(int(w) for w in windows)
        self.alarm_confidence = float(alarm_confidence)
        self.band_floor = float(band_floor)
        self.band_margin = float(band_margin)
        self.directions = dict(DEFAULT_DIRECTIONS if directions is None else directions)
        self.pool_positions = bool(pool_positions)
        self.min_windows = dict(DEFAULT_MIN_WINDOWS if min_windows is None else min_windows)

    def _min_window(self, name: str) -> int:
        return int(self.min_windows.get(generic_feature(name), 1))

    def _dir(self, names: Sequence[str]) -> np.ndarray:
        return np.array([self.directions.get(generic_feature(n), 0) for n in names],
                        dtype=np.float64)

    @staticmethod
    def _oriented(s: np.ndarray, d: np.ndarray) -> np.ndarray:
        """Signed statistic along the fault direction (``|s|`` where ``d == 0``)."""
        return np.where(d == 0, np.abs(s), d * s)

    def fit(self, healthy_sequences: Sequence[np.ndarray],
            feature_names: Sequence[str]) -> FaultDetector:
        """Learn the bands from healthy flight sequences of the design campaign.

        ``healthy_sequences``: one (n_flights_i, n_features) array of standardised residuals per
        monitored actuator history (flights in order), columns in ``feature_names`` order.
        """
        names = list(feature_names)
        dirs = self._dir(names)
        band = np.full((len(names), len(self.windows)), self.band_floor)
        seen = np.zeros(len(names), dtype=np.int64)
        for seq in healthy_sequences:
            seq = np.asarray(seq, dtype=np.float64).reshape(-1, len(names))
            seen += np.isfinite(seq).sum(axis=0)
            for k, w in enumerate(self.windows):
                s = self._oriented(running_statistics(seq, w), dirs[np.newaxis, :])
                with np.errstate(invalid="ignore"):
                    m = np.nanmax(np.where(np.isfinite(s), s, -np.inf), axis=0)
                band[:, k] = np.maximum(band[:, k], m + self.band_margin)
        if self.pool_positions:
            gen = [generic_feature(n) for n in names]
            for g in set(gen):
                idx = [i for i, x in enumerate(gen) if x == g]
                band[idx] = band[idx].max(axis=0)
        self.feature_names_ = names
        self.band_ = band
        self.n_healthy_flights_ = seen
        return self

    def _check(self) -> None:
        if not hasattr(self, "band_"):
            raise RuntimeError("FaultDetector is not fitted")

    def bands(self) -> dict[str, list[float]]:
        """Feature -> band per window (standard errors)."""
        self._check()
        return {n: self.band_[i].tolist() for i, n in enumerate(self.feature_names_)}

    @property
    def z_alarm(self) -> float:
        """Standard errors beyond the band at which the confidence reaches the alarm level."""
        return float(ndtri(self.alarm_confidence))

    def new_state(self, unit: str) -> DetectionState:
        self._check()
        return DetectionState.new(unit, unit_features(unit, self.feature_names_))

    def confidence_sequence(self, z: np.ndarray, feature_names: Sequence[str]) -> np.ndarray:
        """Confidence of every flight of a sequence, (n_flights, n_features), vectorised."""
        self._check()
        idx = [self.feature_names_.index(n) for n in feature_names]
        z = np.asarray(z, dtype=np.float64).reshape(-1, len(idx))
        conf = np.zeros(z.shape)
        min_w = np.array([self._min_window(n) for n in feature_names])
        n_seen = np.cumsum(np.isfinite(z), axis=0)
        for k, w in enumerate(self.windows):
            s = self._oriented(running_statistics(z, w),
                               self._dir(feature_names)[np.newaxis, :])
            c = ndtr(s - self.band_[idx, k][np.newaxis, :])
            allowed = (w >= min_w)[np.newaxis, :] & (n_seen >= min_w[np.newaxis, :])
            conf = np.fmax(conf, np.where(np.isfinite(c) & allowed, c, 0.0))
        return conf

    def update(self, state: DetectionState, z: Mapping[str, float]) -> DetectionResult:
        """Add one flight's residuals to ``state`` (in place) and evaluate the alarm."""
        self._check()
        keep = max(self.windows)
        conf: dict[str, float] = {}
        for f in state.features:
            hist = state.history.setdefault(f, [])
            v = z.get(f, math.nan)
            if v is not None and math.isfinite(v):
                hist.append(float(v))
                del hist[:-keep]
            i = self.feature_names_.index(f)
            d = self.directions.get(generic_feature(f), 0)
            min_w = self._min_window(f)
            c = 0.0
            for k, w in enumerate(self.windows):
                if len(hist) < min_w:
                    break
                if w < min_w:
                    continue
                last = hist[-w:]
                s = sum(last) / math.sqrt(len(last))
                s = abs(s) if d == 0 else d * s
                c = max(c, float(ndtr(s - self.band_[i, k])))
            conf[f] = c
        state.n_flights += 1
        state.confidence = conf
        firing = [f for f, c in conf.items() if c >= self.alarm_confidence]
        new_alarm = bool(firing) and not state.alarm
        if new_alarm:
            state.alarm = True
            state.alarm_flight = state.n_flights
            state.alarm_features = firing
        return DetectionResult(conf, max(conf.values(), default=0.0), state.alarm, new_alarm,
                               list(state.alarm_features))

    def to_dict(self) -> dict[str, Any]:
        self._check()
        return {"format": DETECTOR_FORMAT, "windows": list(self.windows),
                "alarm_confidence": self.alarm_confidence, "band_floor": self.band_floor,
                "band_margin": self.band_margin, "directions": dict(self.directions),
                "pool_positions": self.pool_positions,
                "min_windows": dict(self.min_windows),
                "feature_names": list(self.feature_names_),
                "band": self.band_.tolist(),
                "n_healthy_flights": self.n_healthy_flights_.tolist()}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> FaultDetector:
        if d.get("format") != DETECTOR_FORMAT:
            raise ValueError(f"not a {DETECTOR_FORMAT} document")
        det = cls(d["windows"], alarm_confidence=float(d["alarm_confidence"]),
                  band_floor=float(d["band_floor"]), band_margin=float(d["band_margin"]),
                  directions={k: int(v) for k, v in d.get("directions", {}).items()},
                  pool_positions=bool(d.get("pool_positions", False)),
                  min_windows={k: int(v) for k, v in d.get("min_windows", {}).items()})
        det.feature_names_ = list(d["feature_names"])
        det.band_ = np.asarray(d["band"], dtype=np.float64).reshape(len(det.feature_names_),
                                                                    len(det.windows))
        det.n_healthy_flights_ = np.asarray(d["n_healthy_flights"], dtype=np.int64)
        return det

