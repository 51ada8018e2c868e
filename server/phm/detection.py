"""Fault detection: running feature distributions against their healthy baselines.

Time base: one update per flight, per monitored unit (an actuator ``WL1``/``WL2``/``WT`` with
its six features, and a winglet drive's rod-end play ``F_REWEAR``). Inputs are the standardised
residuals ``z`` of :class:`server.phm.baselines.FleetBaseline` (dimensionless, N(0, 1) on
healthy flights by construction).

Self-reference: each actuator against its own healthy start
-----------------------------------------------------------
Production tolerances (magnet flux, friction, gear play) give every actuator its own offset
from the fleet baseline; for ``F_DMD`` this offset is four to five times the flight-to-flight
scatter on the design campaign (docs/TUNING.md, Detection). The residual is therefore
modelled as ``z = u + e`` with an actuator offset ``u ~ N(0, tau^2)`` and flight noise
``e ~ N(0, sigma^2)``; ``tau`` and ``sigma`` are estimated per generic feature on the healthy
design sequences. The first ``reference_flights`` valid residuals of each actuator
after installation (or maintenance) form its reference; every flight is tested against the
flights *before* it::

    n = reference flights so far,  n_eff = n (n <= 2) or n / 1.57 (median of n),
    u_hat = n_eff tau^2 / (n_eff tau^2 + sigma^2) * median(reference),
    var_u = tau^2 sigma^2 / (n_eff tau^2 + sigma^2),
    z_self = (z - u_hat) / sqrt(sigma^2 + var_u)

(the empirical-Bayes posterior of ``u``; unit variance on healthy flights). With no reference
this is the fleet test, ``z / sqrt(sigma^2 + tau^2)``. The detector below runs on ``z_self``.
A fault already present during the reference flights is partly absorbed into the reference:
the first flight of an actuator is always judged against the fleet alone.
``F_REWEAR`` keeps the fleet test (``fleet_referenced``): a healthy rod end's play is set by
its manufacturing tolerance, and a worn one moves it far beyond any actuator offset, so a
median of its first flights would absorb an early wear rather than reference a drive.

Running distribution and separation confidence
----------------------------------------------
For each feature the state keeps the self-referenced residuals of the last ``max(windows)``
flights with a valid value. For each window length ``w`` (default 1, 3 and 8 flights) the
running mean of the last ``n = min(w, available)`` residuals, scaled to unit variance, is
``S_w = sqrt(n) mean(z)``; a window raises no alarm until it holds ``w`` residuals (its band
is a full window's). Because ``S_w`` has unit standard error, the confidence that the running
mean lies outside a healthy band ``b_w`` is

    c_w = Phi(|S_w| - b_w),      c = max over w of c_w  in [0, 1].

Bands for a stated false-alarm rate
-----------------------------------
The bands are set for ``false_alarm_rate`` (alarms per monitored unit and healthy flight).
The rate is shared out among the unit's tests, every (feature, window) allowed to alarm
(``min_windows``), by Sidak's rule: each test may exceed its threshold on a healthy flight
with probability ``q = 1 - (1 - false_alarm_rate)^(1/m)``, ``m`` the unit's tests (a
two-sided feature gives ``q / 2`` to each tail). The healthy statistic is modelled as
``S_w ~ N(0, s_w^2)``, ``s_w`` near 1 if the offsets are right; ``s_w`` is measured on the
healthy design flights by matching the upper ``scale_quantile`` (0.99) quantile of their
judged ``S_w`` (the values :meth:`FaultDetector.update` would judge: full windows, held
through flights without a value; every position together with ``pool_positions``),
``s_w = Q_p(S_w) / z_p``. A tail quantile rather than an RMS or a MAD, because the healthy
tails are heavier than normal (the quantile-matched scale of the one-flight ``F_SE`` is 1.7
times its MAD-based one on the design campaign). A test alarms at ``s_w z_{1-q}``; with the
confidence margin ``z_alarm = ndtri(alarm_confidence)`` the band is

    b_w = max(s_w z_{1-q} - z_alarm, band_floor).

``Q_p`` estimates a fixed quantile of the healthy population, so the band's expected value
does not depend on how many healthy design flights there are (only its precision does),
unlike the largest healthy ``|S_w|``, which grows with them. (A sample 0.99 quantile needs a
few values beyond it: on a pool of fewer than a few hundred judged values it is low and noisy;
those bands mostly rest on the floor.) Under the normal model the realised rate is at most
the stated one: windows overlap and a unit's tests are correlated, and Sidak's share is the
independent case's. A tail heavier than normal beyond ``Q_p`` raises it (the one-flight
``F_SE`` on the simulated campaigns: docs/TUNING.md, Detection).

Flights whose residual is beyond ``window_clip`` (6 flight-scatter units) enter the windows
longer than one flight clipped to it: a single odd flight (heavy-tailed features, e.g. a
flight with few cruise moves) then moves ``S_3`` by at most ``6 / sqrt(3)``, while a
sustained drift is untouched. Windows of ``median_from`` (8) flights or more use the running
median instead of the mean,
``S_w = sqrt(n / (pi/2)) median`` (unit variance on healthy flights too): a minority of odd
flights does not move it at all, at the cost of a less efficient estimate of a slow drift. The
one-flight window keeps the raw value, for step faults.

The unit alarms when ``c`` of any of its features reaches ``alarm_confidence`` (0.98, the
paper's value), i.e. ``|S_w| >= b_w + 2.05``. The short window reacts within one flight to
step faults (SE, BDO); the long window accumulates evidence of slow drifts. The alarm latches
until maintenance: replacing an actuator gives it a fresh state
(:meth:`DetectionState.reset` does the same in place).

The units of one aircraft are judged together (:meth:`FaultDetector.update_units`): every unit
is observed first, then the alarms are decided, so that a winglet drive's friction evidence,
which its partner's drag moves too, is left to the drive of the pair that has moved further
(:func:`partner_held`).

Evidence: a flight's scatter follows its recording
-------------------------------------------------
A feature averages its flight's valid windows (steps, events, cruise time), so the part of its
flight-to-flight scatter that is sampling noise falls as ``1 / n_valid``: a 60 s recording's
residual scatters more than a 300 s one's. With ``w`` the flight's evidence weight (the design
flights' median ``n_valid`` over this flight's, ``FleetBaseline.evidence_weights``) the flight
noise is modelled as ``e ~ N(0, sigma^2 (1 - a) + sigma^2 a w)``, ``a`` the sampling share of
the scatter at typical evidence, learned per generic feature on the healthy design flights
(deviations from each history's median, their robust variance regressed on ``w`` over bins of
``w``; the design flies recordings of several lengths). A flight then gets the extra variance
``sigma^2 a (w - 1)`` (negative for a recording longer than typical: a tighter test),
``evidence_variance_`` holding ``sigma^2 a`` per feature; the bands are learned on statistics
standardised the same way, so one model serves 60, 120 and 300 s recordings and a fleet that
mixes them. ``a`` is at most ``MAX_EVIDENCE_SHARE``; a design of one recording length (too
narrow a spread of ``w`` to regress on) learns ``a = 0``, the constant scatter.

The test is one-sided along each fault's physical direction (``DEFAULT_DIRECTIONS``: every
feature grows with its fault), ``|S_w|`` being replaced by ``direction * S_w``, and one
band serves a generic feature on every position (``pool_positions``: its scale is measured on
the healthy flights of every position together).

The tuned values are the defaults of :class:`DetectionConfig` (how they were chosen:
docs/TUNING.md, Detection). Everything persists as JSON (``to_dict`` / ``from_dict``), never
pickle.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

import numpy as np
from scipy.special import ndtr, ndtri

from server.vocabulary import (
    GENERIC_FEATURES,
    OWN_FEATURE,
    POSITIONS,
    PROGRESSIVE,
    REWEAR_FEATURE,
    WINGLET_PAIR,
)

__all__ = [
    "DETECTOR_FORMAT",
    "DEFAULT_DIRECTIONS",
    "DetectionConfig",
    "DETECTION_DEFAULTS",
    "generic_feature",
    "STATE_FORMAT",
    "UNITS",
    "unit_features",
    "DetectionState",
    "DetectionResult",
    "Observation",
    "PAIR_COUPLED_FEATURES",
    "partner_held",
    "FaultDetector",
    "running_statistics",
    "self_referenced_sequence",
    "offset_components",
]

DETECTOR_FORMAT = "ema-detector/2"
#: /1 bands were the largest healthy ``|S_w|``; its documents load with the bands they carry
_DETECTOR_FORMATS = (DETECTOR_FORMAT, "ema-detector/1")
STATE_FORMAT = "ema-detection-state/2"
_STATE_FORMATS = (STATE_FORMAT, "ema-detection-state/1")  # /1 had no reference
#: variance of a sample median over that of the mean (normal samples, large n)
_MEDIAN_VARIANCE_FACTOR = math.pi / 2
#: monitored units and the prefix of their feature names: the actuators
UNITS: tuple[str, ...] = POSITIONS
#: largest sampling share ``a`` of a feature's flight scatter: some scatter is never sampling
#: noise (conditions the covariates miss), so a very long recording keeps a band of its own
MAX_EVIDENCE_SHARE = 0.95
#: the evidence weights of a design must spread by this factor (90th over 10th percentile)
#: to regress the scatter on them; below it ``a = 0``
MIN_EVIDENCE_SPREAD = 1.5
_EVIDENCE_BINS = 8
#: generic features a winglet drive's partner moves through the tab (:func:`partner_held`)
PAIR_COUPLED_FEATURES: tuple[str, ...] = (OWN_FEATURE["MTEL"],)


@dataclass(frozen=True)
class DetectionConfig:
    """Hyper-parameters of :class:`FaultDetector`; the defaults are the tuned values
    (docs/TUNING.md, Detection). A fitted detector stores its values in its document.

    Attributes
    ----------
    windows:
        Running-window lengths [flight]: 1 reacts within one flight to step faults (SE, BDO);
        3 and 8 accumulate the evidence of slow drifts.
    alarm_confidence:
        Confidence at which a unit alarms [-]: the paper's 0.98, ``|S_w| >= b_w + 2.05``.
    band_floor:
        Smallest band ``b_w`` [standard error]: a feature with few healthy flights still gets
        at least a 3-standard-error band (first-cut value).
    false_alarm_rate:
        False alarms per monitored unit and healthy flight the bands are set for [1/flight],
        shared out among the unit's (feature, window) tests (module docstring).
    scale_quantile:
        Upper quantile of the healthy judged ``S_w`` at which its normal scale ``s_w`` is
        matched, ``s_w = Q_p / z_p`` [-]: far enough out to see heavier-than-normal tails,
        near enough to be estimated from a few hundred healthy flights.
    directions:
        Generic feature -> +1 (the fault makes it grow), -1 (fall), 0 (either) [-]: every
        feature grows with its fault, so the test is one-sided.
    pool_positions:
        One band per generic feature, the largest over the positions: more healthy flights
        behind each band, the same physics on every actuator.
    min_windows:
        Generic feature -> shortest window allowed to raise an alarm [flight]: 3 for the five
        progressive faults' features (they build up over hundreds of flights, while single
        healthy flights stray far); absent (F_SE, F_BDO, step faults): 1.
    reference_flights:
        Valid flights of each actuator that form its own reference [flight]: 6 keeps the
        offset's uncertainty at about 1/4 of the flight scatter's variance and leaves most
        healthy design flights to learn the bands on; 0 is the pure fleet test.
    window_clip:
        Residuals are clipped to +-``window_clip`` in windows longer than one flight
        [flight-scatter sd]: one odd flight moves ``S_3`` by at most 6 / sqrt(3); ``inf`` off.
    median_from:
        Windows of at least this many flights use the running median [flight]: a minority of
        odd flights does not move the 8-flight statistic; 0 never.
    fleet_referenced:
        Generic features tested against the fleet, not the actuator's own first flights [-]:
        ``F_REWEAR``, which a worn rod end moves far beyond any actuator offset.
    """

    windows: tuple[int, ...] = (1, 3, 8)
    alarm_confidence: float = 0.98
    band_floor: float = 3.0
    false_alarm_rate: float = 3e-5
    scale_quantile: float = 0.99
    directions: Mapping[str, int] = field(
        default_factory=lambda: MappingProxyType(dict.fromkeys(GENERIC_FEATURES, 1)))
    pool_positions: bool = True
    min_windows: Mapping[str, int] = field(
        default_factory=lambda: MappingProxyType({OWN_FEATURE[m]: 3 for m in PROGRESSIVE}))
    reference_flights: int = 6
    window_clip: float = 6.0
    median_from: int = 8
    fleet_referenced: tuple[str, ...] = (REWEAR_FEATURE,)


#: the tuned detector (``FaultDetector()``)
DETECTION_DEFAULTS = DetectionConfig()
#: physical direction of each generic feature under its fault: +1 grows, -1 falls, 0 either
DEFAULT_DIRECTIONS: dict[str, int] = dict(DETECTION_DEFAULTS.directions)
#: generic features tested against the fleet rather than the actuator's own first flights
DEFAULT_FLEET_REFERENCED: tuple[str, ...] = DETECTION_DEFAULTS.fleet_referenced
#: shortest alarm window per generic feature
DEFAULT_MIN_WINDOWS: dict[str, int] = dict(DETECTION_DEFAULTS.min_windows)


def generic_feature(name: str) -> str:
    """``"WL1.F_TTS"`` -> ``"F_TTS"``."""
    return name.split(".", 1)[-1]


def unit_features(unit: str, feature_names: Iterable[str]) -> list[str]:
    """Feature names (``"<unit>.F_*"``) that belong to ``unit``."""
    return [f for f in feature_names if f.split(".", 1)[0] == unit]


def _median_n_eff(n: np.ndarray | int) -> np.ndarray:
    """Effective sample size of a median of ``n`` values (mean for n <= 2)."""
    n = np.asarray(n, dtype=np.float64)
    return np.where(n > 2, n / _MEDIAN_VARIANCE_FACTOR, n)


def running_statistics(z: np.ndarray, window: int, *, median: bool = False) -> np.ndarray:
    """``S_w`` for every flight of a sequence: (n_flights, n_features) -> same shape.

    ``S_w = sqrt(n) mean`` of the last ``n = min(window, available)`` valid residuals, or with
    ``median`` ``sqrt(n / (pi/2)) median`` (unit variance on healthy flights as well, and
    unmoved by a minority of odd flights). NaN residuals (no valid window in that flight) are
    skipped: the window then reaches further back. Before any valid residual the statistic is
    NaN. Vectorised per feature column.
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
        k = np.arange(1, v.size + 1)
        lo = np.maximum(k - window, 0)
        n = k - lo
        if median:
            padded = np.r_[np.full(window - 1, np.nan), v]
            windows = np.lib.stride_tricks.sliding_window_view(padded, window)
            s = np.nanmedian(windows, axis=1) * np.sqrt(_median_n_eff(n))
        else:
            cs = np.r_[0.0, np.cumsum(v)]
            s = (cs[k] - cs[lo]) / np.sqrt(n)
        full = np.full(col.size, np.nan)
        full[ok] = s
        last = np.maximum.accumulate(np.where(np.isfinite(col), np.arange(col.size), -1))
        held = last >= 0
        full[held] = full[last[held]]
        out[:, j] = full
    return out


def _reference_posterior(ref: np.ndarray, n: np.ndarray, sigma: np.ndarray,
                         tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Offset estimate ``u_hat`` and the total residual sd ``sqrt(sigma^2 + var_u)`` from the
    median ``ref`` of ``n`` reference residuals (arrays broadcast; ``n == 0`` -> fleet test)."""
    n = np.asarray(n, dtype=np.float64)
    n_eff = _median_n_eff(n)
    s2, t2 = sigma**2, tau**2
    denom = n_eff * t2 + s2
    u_hat = np.where(n > 0, n_eff * t2 / denom * np.nan_to_num(ref), 0.0)
    var_u = t2 * s2 / denom
    return u_hat, np.sqrt(s2 + var_u)


def self_referenced_sequence(z: np.ndarray, sigma: np.ndarray, tau: np.ndarray,
                             reference_flights: int,
                             extra_variance: np.ndarray | None = None) -> np.ndarray:
    """Self-referenced residuals of a flight sequence (n_flights, n_features), each flight
    against the median of the first ``reference_flights`` valid residuals *before* it;
    ``extra_variance`` (same shape) adds to each flight's scatter. NaN stays NaN."""
    z = np.asarray(z, dtype=np.float64)
    z = z[:, np.newaxis] if z.ndim == 1 else z
    extra = np.zeros(z.shape) if extra_variance is None else np.asarray(
        extra_variance, dtype=np.float64).reshape(z.shape)
    out = np.full(z.shape, np.nan)
    for j in range(z.shape[1]):
        col = z[:, j]
        ok = np.flatnonzero(np.isfinite(col))
        first = col[ok[:reference_flights]]
        # reference median and count seen by each flight (flights before it only)
        n_before = np.minimum(np.searchsorted(ok, np.arange(col.size)), reference_flights)
        medians = np.array([np.median(first[:k]) if k else 0.0
                            for k in range(min(reference_flights, first.size) + 1)])
        ref = medians[n_before]
        u_hat, sd = _reference_posterior(ref, n_before, sigma[j], tau[j])
        out[:, j] = (col - u_hat) / np.sqrt(sd**2 + extra[:, j])
    return out


def _generic_groups(names: Sequence[str]) -> list[list[int]]:
    """Column indices of each generic feature (``WL1.F_TTS``, ``WT.F_TTS`` -> one group)."""
    gen = [generic_feature(n) for n in names]
    return [[i for i, x in enumerate(gen) if x == g] for g in dict.fromkeys(gen)]


def offset_components(healthy_sequences: Sequence[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Within-actuator sd ``sigma`` and between-actuator sd ``tau`` of each column, from
    healthy sequences (one per actuator history): robust within scatter (1.4826 MAD of the
    deviations from each sequence's median), ``tau^2`` = variance of the sequence medians less
    their sampling variance (``pi/2 sigma^2 / n``), floored at 0."""
    seqs = [np.asarray(q, dtype=np.float64) for q in healthy_sequences]
    n_feat = seqs[0].shape[1]
    sigma = np.ones(n_feat)
    tau = np.zeros(n_feat)
    for j in range(n_feat):
        cols = [q[:, j][np.isfinite(q[:, j])] for q in seqs]
        cols = [c for c in cols if c.size >= 2]
        if len(cols) < 2:
            continue
        dev = np.concatenate([c - np.median(c) for c in cols])
        n = np.array([c.size for c in cols], dtype=np.float64)
        # the deviations from a sample's own median shrink by about (n - 1) / n
        mad = float(np.median(np.abs(dev))) * 1.4826 * math.sqrt(float(np.mean(n / (n - 1))))
        if not mad > 0:
            continue
        sigma[j] = mad
        medians = np.array([np.median(c) for c in cols])
        t2 = float(np.var(medians, ddof=1)) - _MEDIAN_VARIANCE_FACTOR * mad**2 * float(
            np.mean(1.0 / n))
        tau[j] = math.sqrt(max(t2, 0.0))
    return sigma, tau


def evidence_shares(healthy_sequences: Sequence[np.ndarray],
                    evidence: Sequence[np.ndarray], groups: Sequence[Sequence[int]]
                    ) -> np.ndarray:
    """The sampling share ``a`` of each column's flight scatter (module docstring), one per
    group of columns (a generic feature's positions): the robust variance (1.4826 MAD,
    squared) of the deviations from each history's median, in ``_EVIDENCE_BINS`` bins of the
    evidence weight ``w``, fitted as ``c0 + c1 w``; ``a = c1 / (c0 + c1)`` in ``[0,
    MAX_EVIDENCE_SHARE]``, 0 where ``w`` spreads too little to tell."""
    n_feat = np.asarray(healthy_sequences[0]).shape[1]
    share = np.zeros(n_feat)
    for idx in groups:
        dev, wts = [], []
        for q, e in zip(healthy_sequences, evidence, strict=True):
            for j in idx:
                col, w = np.asarray(q)[:, j], np.asarray(e)[:, j]
                ok = np.isfinite(col) & np.isfinite(w) & (w > 0)
                if ok.sum() >= 2:
                    dev.append(col[ok] - np.median(col[ok]))
                    wts.append(w[ok])
        if not dev:
            continue
        d, w = np.concatenate(dev), np.concatenate(wts)
        lo, hi = np.quantile(w, [0.1, 0.9])
        if d.size < 20 * _EVIDENCE_BINS or not hi >= MIN_EVIDENCE_SPREAD * lo:
            continue
        edges = np.quantile(w, np.linspace(0.0, 1.0, _EVIDENCE_BINS + 1))
        which = np.clip(np.searchsorted(edges, w, side="right") - 1, 0, _EVIDENCE_BINS - 1)
        wb, vb, nb = [], [], []
        for b in range(_EVIDENCE_BINS):
            sel = which == b
            if sel.sum() >= 10:
                wb.append(float(np.mean(w[sel])))
                vb.append((1.4826 * float(np.median(np.abs(d[sel])))) ** 2)
                nb.append(float(sel.sum()))
        if len(wb) < 3:
            continue
        c1, c0 = np.polyfit(np.array(wb), np.array(vb), 1, w=np.sqrt(np.array(nb)))
        total = c0 + c1
        if total > 0:
            share[list(idx)] = min(max(c1 / total, 0.0), MAX_EVIDENCE_SHARE)
    return share


def _at_typical_evidence(q: np.ndarray, w: np.ndarray, share: np.ndarray) -> np.ndarray:
    """A history's residuals with each flight's deviation from the history's median brought
    to typical evidence: divided by ``sqrt(1 - a + a w)``, its scatter's ratio to ``sigma``."""
    factor = np.sqrt(1.0 - share + share * np.where(np.isfinite(w), w, 1.0))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # a column without a value stays NaN
        med = np.nanmedian(q, axis=0, keepdims=True)
    return med + (q - med) / factor


@dataclass
class DetectionState:
    """Per-unit state carried from flight to flight (JSON-serialisable)."""

    unit: str
    features: list[str]
    #: last self-referenced residuals, oldest first
    history: dict[str, list[float]] = field(default_factory=dict)
    #: the first valid residuals ``z`` since installation: the actuator's own reference
    reference: dict[str, list[float]] = field(default_factory=dict)
    n_flights: int = 0  # flights seen since the last reset
    alarm: bool = False
    alarm_flight: int | None = None  # n_flights count at which the alarm was raised
    alarm_features: list[str] = field(default_factory=list)
    confidence: dict[str, float] = field(default_factory=dict)  # latest, per feature

    @classmethod
    def new(cls, unit: str, features: Iterable[str]) -> DetectionState:
        feats = list(features)
        return cls(unit=unit, features=feats, history={f: [] for f in feats},
                   reference={f: [] for f in feats}, confidence={f: 0.0 for f in feats})

    def reset(self) -> None:
        """Forget the history and the reference, clear the alarm (after maintenance: a new
        actuator learns its own reference)."""
        self.history = {f: [] for f in self.features}
        self.reference = {f: [] for f in self.features}
        self.n_flights = 0
        self.alarm = False
        self.alarm_flight = None
        self.alarm_features = []
        self.confidence = {f: 0.0 for f in self.features}

    def to_dict(self) -> dict[str, Any]:
        return {"format": STATE_FORMAT, "unit": self.unit, "features": list(self.features),
                "history": {k: [float(x) for x in v] for k, v in self.history.items()},
                "reference": {k: [float(x) for x in v] for k, v in self.reference.items()},
                "n_flights": self.n_flights, "alarm": self.alarm,
                "alarm_flight": self.alarm_flight, "alarm_features": list(self.alarm_features),
                "confidence": {k: float(v) for k, v in self.confidence.items()}}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> DetectionState:
        if d.get("format") not in _STATE_FORMATS:
            raise ValueError(f"not a {STATE_FORMAT} document")
        # a /1 state has no reference: the actuator learns one from its next flights
        return cls(unit=str(d["unit"]), features=list(d["features"]),
                   history={k: [float(x) for x in v] for k, v in d["history"].items()},
                   reference={k: [float(x) for x in v]
                              for k, v in (d.get("reference") or {}).items()},
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
    #: self-referenced residual of each feature with a valid value this flight
    z_self: dict[str, float] = field(default_factory=dict)
    #: the actuator's own offset ``u_hat`` (``z`` units) removed from each feature
    offset: dict[str, float] = field(default_factory=dict)
    #: features whose evidence was left to the partner drive this flight (:func:`partner_held`)
    held: list[str] = field(default_factory=list)


@dataclass(frozen=True)
class Observation:
    """One flight's judgement of one unit's features, before the alarm is decided."""

    confidence: dict[str, float]  # per feature, in [0, 1]
    #: per pair-coupled feature (``PAIR_COUPLED_FEATURES``), the median of its last
    #: ``max(windows)`` self-referenced residuals along the fault's direction, unclipped (-inf
    #: with none): how far the unit has moved
    level: dict[str, float]
    z_self: dict[str, float]
    offset: dict[str, float]


def partner_held(levels: Mapping[str, Mapping[str, float]]) -> dict[str, list[str]]:
    """The features of each winglet drive whose evidence belongs to its partner.

    ``levels``: unit -> feature -> :attr:`Observation.level` of one flight. The active drive
    back-drives its attached standby through the tab, so the standby's screw and motor drag is
    part of the hinge work in the active drive's friction ratio: an MTEL-aged partner raises
    it by 0.44-0.49 of its own rise (``python bench/partner_drag.py``: 6.5 flight-scatter sd at
    half the failure severity). Of the pair, a coupled feature's evidence is the drive's that
    has moved further (the levels, not the alarm statistics: those are clipped, and late in a
    life both drives' would stand at the clip); the other drive's is held (it raises no
    alarm), so an aged drive alarms on itself and its healthy partner does not. A fault of a
    drive's own still moves that drive further (its partner sees under half of it)."""
    held: dict[str, list[str]] = {}
    for unit, partner in ((WINGLET_PAIR[0], WINGLET_PAIR[1]), (WINGLET_PAIR[1], WINGLET_PAIR[0])):
        if unit not in levels or partner not in levels:
            continue
        for g in PAIR_COUPLED_FEATURES:
            mine = levels[unit].get(f"{unit}.{g}", -math.inf)
            theirs = levels[partner].get(f"{partner}.{g}", -math.inf)
            if theirs > mine:
                held.setdefault(unit, []).append(f"{unit}.{g}")
    return held


class FaultDetector:
    """Separation-confidence detector with bands learned on healthy design flights.

    Parameters
    ----------
    The fields of :class:`DetectionConfig` (units and reasons there), defaults
    :data:`DETECTION_DEFAULTS`; ``None`` for a mapping or ``fleet_referenced`` is its default.

    windows : running-window lengths in flights.
    alarm_confidence : confidence at which a unit alarms.
    band_floor : smallest allowed band ``b_w`` (in standard errors).
    false_alarm_rate : false alarms per monitored unit and healthy flight the bands are set
        for, shared out among the unit's tests (module docstring).
    scale_quantile : upper quantile of the healthy ``S_w`` that sets its scale ``s_w``.
    directions : generic feature -> +1 (the fault makes it grow), -1 (fall) or 0 (either);
        the statistic is ``direction * S_w`` (one-sided test), ``|S_w|`` for 0 / unknown.
    pool_positions : one band per generic feature, its scale measured on every position's
        healthy flights together.
    min_windows : generic feature -> shortest window allowed to raise an alarm (flights of
        evidence; 1 when absent). F_MTWEAR has a value only on flights that pressed both
        screw flanks, so its 3 flights are the last 3 such flights.
    window_clip : residuals are clipped to +-``window_clip`` in windows longer than one
        flight (module docstring); ``inf`` disables it.
    median_from : windows of at least this many flights use the running median instead of
        the mean (module docstring); 0 never.
    reference_flights : valid flights of each actuator that form its own reference (module
        docstring); 0 disables the self-reference (pure fleet test).
    fleet_referenced : generic features that skip the self-reference: their residual is
        taken against the fleet, scaled by the whole healthy scatter sqrt(sigma^2 + tau^2).
    """

    def __init__(self, windows: Sequence[int] = DETECTION_DEFAULTS.windows, *,
                 alarm_confidence: float = DETECTION_DEFAULTS.alarm_confidence,
                 band_floor: float = DETECTION_DEFAULTS.band_floor,
                 false_alarm_rate: float = DETECTION_DEFAULTS.false_alarm_rate,
                 scale_quantile: float = DETECTION_DEFAULTS.scale_quantile,
                 directions: Mapping[str, int] | None = None,
                 pool_positions: bool = DETECTION_DEFAULTS.pool_positions,
                 min_windows: Mapping[str, int] | None = None,
                 reference_flights: int = DETECTION_DEFAULTS.reference_flights,
                 window_clip: float = DETECTION_DEFAULTS.window_clip,
                 median_from: int = DETECTION_DEFAULTS.median_from,
                 fleet_referenced: Sequence[str] | None = None) -> None:
        if not windows or min(windows) < 1:
            raise ValueError("windows must be positive flight counts")
        if not 0.5 < alarm_confidence < 1.0:
            raise ValueError("alarm_confidence must lie in (0.5, 1)")
        self.windows = tuple(int(w) for w in windows)
        self.alarm_confidence = float(alarm_confidence)
        self.band_floor = float(band_floor)
        if false_alarm_rate is None or not 0.0 < false_alarm_rate < 1.0:
            raise ValueError("false_alarm_rate must lie in (0, 1)")
        self.false_alarm_rate: float | None = float(false_alarm_rate)
        if not 0.5 < scale_quantile < 1.0:
            raise ValueError("scale_quantile must lie in (0.5, 1)")
        self.scale_quantile = float(scale_quantile)
        self.directions = dict(DETECTION_DEFAULTS.directions if directions is None
                               else directions)
        self.pool_positions = bool(pool_positions)
        self.min_windows = dict(DETECTION_DEFAULTS.min_windows if min_windows is None
                                else min_windows)
        if reference_flights < 0:
            raise ValueError("reference_flights must be >= 0")
        self.reference_flights = int(reference_flights)
        if not window_clip > 0:
            raise ValueError("window_clip must be positive")
        self.window_clip = float(window_clip)
        self.median_from = int(median_from)
        self.fleet_referenced = tuple(DETECTION_DEFAULTS.fleet_referenced
                                      if fleet_referenced is None else fleet_referenced)

    @classmethod
    def from_config(cls, config: DetectionConfig) -> FaultDetector:
        """An unfitted detector with the hyper-parameters of ``config``."""
        return cls(config.windows, alarm_confidence=config.alarm_confidence,
                   band_floor=config.band_floor, false_alarm_rate=config.false_alarm_rate,
                   scale_quantile=config.scale_quantile,
                   directions=config.directions, pool_positions=config.pool_positions,
                   min_windows=config.min_windows, reference_flights=config.reference_flights,
                   window_clip=config.window_clip, median_from=config.median_from,
                   fleet_referenced=config.fleet_referenced)

    @property
    def config(self) -> DetectionConfig:
        """This detector's hyper-parameters (``false_alarm_rate`` is None for bands loaded
        from an ``ema-detector/1`` document: those were the largest healthy ``|S_w|``)."""
        return DetectionConfig(
            windows=self.windows, alarm_confidence=self.alarm_confidence,
            band_floor=self.band_floor,
            # None for bands loaded from an ema-detector/1 document (docstring)
            false_alarm_rate=self.false_alarm_rate,  # type: ignore[arg-type]
            scale_quantile=self.scale_quantile,
            directions=MappingProxyType(dict(self.directions)),
            pool_positions=self.pool_positions,
            min_windows=MappingProxyType(dict(self.min_windows)),
            reference_flights=self.reference_flights, window_clip=self.window_clip,
            median_from=self.median_from, fleet_referenced=self.fleet_referenced)

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
            feature_names: Sequence[str],
            evidence: Sequence[np.ndarray] | None = None) -> FaultDetector:
        """Learn the bands from healthy flight sequences of the design campaign.

        ``healthy_sequences``: one (n_flights_i, n_features) array of standardised residuals per
        monitored actuator history (flights in order), columns in ``feature_names`` order;
        ``evidence``: the flights' evidence weights, same shapes (None: every flight typical).
        First the sampling share of the scatter (module docstring, Evidence), then the offset
        components (``sigma``, ``tau``) per generic feature at typical evidence, then each
        (feature, window)'s healthy scale ``s_w`` on the self-referenced residuals of the same
        sequences, and its band for ``false_alarm_rate`` (module docstring).
        """
        names = list(feature_names)
        seqs = [np.asarray(q, dtype=np.float64).reshape(-1, len(names))
                for q in healthy_sequences]
        weights = (None if evidence is None else
                   [np.asarray(e, dtype=np.float64).reshape(-1, len(names)) for e in evidence])
        share = np.zeros(len(names))
        if weights is not None and self.reference_flights > 0:
            share = evidence_shares(seqs, weights, _generic_groups(names)
                                    if self.pool_positions else [[i] for i in range(len(names))])
        typical = (seqs if weights is None else
                   [_at_typical_evidence(q, e, share) for q, e in zip(seqs, weights, strict=True)])
        if self.reference_flights == 0:  # the fleet test: z as it is
            sigma, tau = np.ones(len(names)), np.zeros(len(names))
        else:
            sigma, tau = offset_components(typical)
            if self.pool_positions:  # one actuator population per generic feature
                for idx in _generic_groups(names):
                    sigma[idx] = np.sqrt(np.mean(sigma[idx] ** 2))
                    tau[idx] = np.sqrt(np.mean(tau[idx] ** 2))
            self.evidence_variance_ = share * sigma**2
            fleet = np.array([generic_feature(n) in self.fleet_referenced for n in names],
                             dtype=bool)
            sigma[fleet] = np.sqrt(sigma[fleet] ** 2 + tau[fleet] ** 2)
            tau[fleet] = 0.0  # no offset to learn: the reference is the fleet's
        if self.reference_flights == 0:
            self.evidence_variance_ = np.zeros(len(names))
        self.within_std_, self.between_std_ = sigma, tau
        seen = np.zeros(len(names), dtype=np.int64)
        for seq in seqs:
            seen += np.isfinite(seq).sum(axis=0)
        self.feature_names_ = names
        stats = self.healthy_statistics(seqs, names, weights)
        groups = (_generic_groups(names) if self.pool_positions
                  else [[i] for i in range(len(names))])
        scale = np.full((len(names), len(self.windows)), np.nan)
        for idx in groups:
            two_sided = self.directions.get(generic_feature(names[idx[0]]), 0) == 0
            for k in range(len(self.windows)):
                scale[idx, k] = self._scale_of(np.concatenate([stats[k][i] for i in idx]),
                                               two_sided)
        self.healthy_scale_ = scale
        self.band_ = self._bands_for(scale)
        self.n_healthy_flights_ = seen
        return self

    def evidence_extra(self, weights: np.ndarray,
                       feature_names: Sequence[str] | None = None) -> np.ndarray:
        """The extra variance of flights with evidence weights ``weights`` (..., n_features in
        ``feature_names`` order, default the fitted ones): ``sigma^2 a (w - 1)``, 0 where no
        weight is known."""
        names = self.feature_names_ if feature_names is None else list(feature_names)
        idx = [self.feature_names_.index(n) for n in names]
        w = np.asarray(weights, dtype=np.float64)
        return np.where(np.isfinite(w), self.evidence_variance_[idx] * (w - 1.0), 0.0)

    def flight_variance(self, evidence: Mapping[str, float] | None = None,
                        extra_variance: Mapping[str, float] | None = None) -> dict[str, float]:
        """Feature -> variance added to one flight's scatter: its evidence's
        (:meth:`evidence_extra`) and a noisier sensor's (``extra_variance``)."""
        out = dict(extra_variance or {})
        for f, w in (evidence or {}).items():
            if f in self.feature_names_ and math.isfinite(w):
                i = self.feature_names_.index(f)
                if self.evidence_variance_[i]:
                    out[f] = out.get(f, 0.0) + float(self.evidence_variance_[i] * (w - 1.0))
        return out

    def _scale_of(self, s: np.ndarray, two_sided: bool) -> float:
        """Normal scale of healthy judged statistics: their ``scale_quantile`` quantile (Weibull
        plotting position, ``p (N + 1)``) over the standard-normal one (of ``|S|`` for a
        two-sided feature); NaN without any."""
        if not s.size:
            return math.nan
        p = self.scale_quantile
        z_p = float(ndtri(0.5 + p / 2) if two_sided else ndtri(p))
        return float(np.quantile(s, p, method="weibull")) / z_p

    def healthy_statistics(self, healthy_sequences: Sequence[np.ndarray],
                           feature_names: Sequence[str],
                           evidence: Sequence[np.ndarray] | None = None
                           ) -> list[list[np.ndarray]]:
        """The judged statistics of healthy sequences, ``[window][feature]`` -> 1-D array of
        every flight's oriented ``S_w`` (``|S_w|`` for a two-sided feature) once the window
        is full, as :meth:`update` judges it (held through flights without a value).
        Windows shorter than a feature's ``min_windows`` count from ``w`` flights on. Needs
        the fitted offsets (``within_std_``, ``between_std_``); :meth:`fit` calls it.
        ``evidence``: each flight's evidence weights (None: every flight typical)."""
        names = list(feature_names)
        dirs = self._dir(names)[np.newaxis, :]
        min_w = np.array([self._min_window(n) for n in names])
        out: list[list[list[np.ndarray]]] = [[[] for _ in names] for _ in self.windows]
        for h, q in enumerate(healthy_sequences):
            q = np.asarray(q, dtype=np.float64).reshape(-1, len(names))
            extra = None if evidence is None else self.evidence_extra(evidence[h], names)
            q = self.self_referenced(q, extra)
            n_seen = np.cumsum(np.isfinite(q), axis=0)
            for k, w in enumerate(self.windows):
                s = self._oriented(running_statistics(self._clipped(q, w), w,
                                                      median=self._median(w)), dirs)
                need = np.where(w >= min_w, np.maximum(w, min_w), w)[np.newaxis, :]
                judged = (n_seen >= need) & np.isfinite(s)
                for j in range(len(names)):
                    out[k][j].append(s[judged[:, j], j])
        return [[np.concatenate(c) if c else np.empty(0) for c in per_w] for per_w in out]

    def tests_per_unit(self, feature_names: Sequence[str] | None = None) -> dict[str, int]:
        """Unit -> its tests, the (feature, window) pairs allowed to alarm."""
        names = self.feature_names_ if feature_names is None else list(feature_names)
        out: dict[str, int] = {}
        for n in names:
            unit = n.split(".", 1)[0]
            out[unit] = out.get(unit, 0) + sum(w >= self._min_window(n) for w in self.windows)
        return out

    def test_quantiles(self, feature_names: Sequence[str] | None = None) -> np.ndarray:
        """``z_{1-q}`` of every feature's tests (n_features,): the standard-normal quantile of
        its share ``q`` of its unit's false-alarm rate (Sidak; ``q / 2`` per side for a
        two-sided feature)."""
        if self.false_alarm_rate is None:
            raise RuntimeError("an ema-detector/1 document states no false-alarm rate")
        names = self.feature_names_ if feature_names is None else list(feature_names)
        m = self.tests_per_unit(names)
        per_test = np.array([-math.expm1(math.log1p(-self.false_alarm_rate)
                                         / max(m[n.split(".", 1)[0]], 1)) for n in names])
        two_sided = self._dir(names) == 0
        return -ndtri(np.where(two_sided, per_test / 2, per_test))

    def _bands_for(self, scale: np.ndarray) -> np.ndarray:
        """Bands (n_features, n_windows) of healthy scales ``s_w``: the alarm threshold
        ``s_w z_{1-q}`` less the confidence margin, floored; no healthy value -> the floor."""
        thr = scale * self.test_quantiles()[:, np.newaxis]
        band = np.fmax(thr - self.z_alarm, self.band_floor)
        return np.where(np.isfinite(band), band, self.band_floor)

    def _check(self) -> None:
        if not hasattr(self, "band_"):
            raise RuntimeError("FaultDetector is not fitted")

    def bands(self) -> dict[str, list[float]]:
        """Feature -> band per window (standard errors)."""
        self._check()
        return {n: self.band_[i].tolist() for i, n in enumerate(self.feature_names_)}

    def _median(self, window: int) -> bool:
        return 0 < self.median_from <= window

    def _clipped(self, z: np.ndarray, window: int) -> np.ndarray:
        return z if window == 1 else np.clip(z, -self.window_clip, self.window_clip)

    def self_referenced(self, z: np.ndarray, extra_variance: np.ndarray | None = None
                        ) -> np.ndarray:
        """Self-referenced residuals of one actuator history (n_flights, all features);
        ``extra_variance`` (same shape) adds to each flight's scatter."""
        return self_referenced_sequence(z, self.within_std_, self.between_std_,
                                        self.reference_flights, extra_variance)

    def _self_one(self, state: DetectionState, f: str, i: int,
                  v: float, extra_variance: float = 0.0) -> tuple[float, float]:
        """``(z_self, u_hat)`` of one feature value against the state's reference;
        ``extra_variance`` adds to the flight scatter (a noisier sensor's share)."""
        ref = state.reference.get(f, [])
        med = float(np.median(ref)) if ref else 0.0
        u_hat, sd = _reference_posterior(np.array(med), np.array(len(ref)),
                                         self.within_std_[i], self.between_std_[i])
        return (v - float(u_hat)) / math.sqrt(float(sd) ** 2 + extra_variance), float(u_hat)

    @property
    def z_alarm(self) -> float:
        """Standard errors beyond the band at which the confidence reaches the alarm level."""
        return float(ndtri(self.alarm_confidence))

    def new_state(self, unit: str) -> DetectionState:
        self._check()
        return DetectionState.new(unit, unit_features(unit, self.feature_names_))

    def confidence_sequence(self, z: np.ndarray, feature_names: Sequence[str],
                            evidence: np.ndarray | None = None) -> np.ndarray:
        """Confidence of every flight of one actuator history (n_flights, n_features) of
        standardised residuals ``z`` (self-referenced here), vectorised over flights;
        ``evidence``: the flights' evidence weights, same shape (None: typical)."""
        self._check()
        idx = [self.feature_names_.index(n) for n in feature_names]
        z = np.asarray(z, dtype=np.float64).reshape(-1, len(idx))
        extra = None if evidence is None else self.evidence_extra(
            np.asarray(evidence, dtype=np.float64).reshape(z.shape), feature_names)
        z = self_referenced_sequence(z, self.within_std_[idx], self.between_std_[idx],
                                     self.reference_flights, extra)
        conf = np.zeros(z.shape)
        min_w = np.array([self._min_window(n) for n in feature_names])
        n_seen = np.cumsum(np.isfinite(z), axis=0)
        for k, w in enumerate(self.windows):
            s = self._oriented(running_statistics(self._clipped(z, w), w,
                                                  median=self._median(w)),
                               self._dir(feature_names)[np.newaxis, :])
            c = ndtr(s - self.band_[idx, k][np.newaxis, :])
            # judged once full, as in :meth:`update`
            allowed = (w >= min_w)[np.newaxis, :] & (n_seen >= np.maximum(w, min_w)[np.newaxis, :])
            conf = np.fmax(conf, np.where(np.isfinite(c) & allowed, c, 0.0))
        return conf

    def update(self, state: DetectionState, z: Mapping[str, float],
               extra_variance: Mapping[str, float] | None = None,
               evidence: Mapping[str, float] | None = None) -> DetectionResult:
        """Add one flight's residuals to ``state`` (in place) and evaluate the alarm
        (:meth:`observe`, then :meth:`decide` with nothing held)."""
        return self.decide(state, self.observe(state, z, extra_variance, evidence))

    def observe(self, state: DetectionState, z: Mapping[str, float],
                extra_variance: Mapping[str, float] | None = None,
                evidence: Mapping[str, float] | None = None) -> Observation:
        """Add one flight's residuals to ``state`` (in place) and judge every feature, without
        deciding the alarm: the chain first sets a winglet drive's evidence beside its
        partner's (:func:`partner_held`).

        ``extra_variance`` (feature -> variance in residual units) widens a feature's flight
        scatter for this flight: the share a sensor measured noisier than in design adds
        (:mod:`server.phm.sensor_health`); ``evidence`` (feature -> evidence weight, module
        docstring) adds the flight's sampling share."""
        self._check()
        extra = self.flight_variance(evidence, extra_variance)
        keep = max(self.windows)
        margin: dict[str, float] = {}
        level: dict[str, float] = {}
        z_self: dict[str, float] = {}
        offset: dict[str, float] = {}
        for f in state.features:
            hist = state.history.setdefault(f, [])
            ref = state.reference.setdefault(f, [])
            i = self.feature_names_.index(f)
            v = z.get(f, math.nan)
            if v is not None and math.isfinite(v):
                z_self[f], offset[f] = self._self_one(state, f, i, float(v),
                                                      extra.get(f, 0.0))
                if len(ref) < self.reference_flights:
                    ref.append(float(v))
                hist.append(z_self[f])
                del hist[:-keep]
            margin[f] = self._margin(f, i, hist)
            if generic_feature(f) in PAIR_COUPLED_FEATURES:  # only the pair rule reads it
                d = self.directions.get(generic_feature(f), 0) or 1
                level[f] = d * float(np.median(hist)) if hist else -math.inf
        state.n_flights += 1
        state.confidence = {f: float(ndtr(m)) for f, m in margin.items()}
        return Observation(dict(state.confidence), level, z_self, offset)

    def _margin(self, f: str, i: int, hist: list[float]) -> float:
        """How far the feature's running statistic stands beyond its band, the largest over
        the judged windows [standard error]; -inf with no window judged."""
        d = self.directions.get(generic_feature(f), 0)
        min_w = self._min_window(f)
        best = -math.inf
        for k, w in enumerate(self.windows):
            if len(hist) < max(w, min_w):
                break  # a window is judged once it is full (its band is a full one's)
            if w < min_w:
                continue
            last = hist[-w:]
            if w > 1:
                last = [min(max(x, -self.window_clip), self.window_clip) for x in last]
            if self._median(w):
                s = float(np.median(last)) * math.sqrt(float(_median_n_eff(len(last))))
            else:
                s = sum(last) / math.sqrt(len(last))
            s = abs(s) if d == 0 else d * s
            best = max(best, s - float(self.band_[i, k]))
        return best

    def update_units(self, states: Mapping[str, DetectionState], z: Mapping[str, float],
                     extra_variance: Mapping[str, float] | None = None,
                     evidence: Mapping[str, float] | None = None
                     ) -> dict[str, DetectionResult]:
        """One flight of every unit of an aircraft: each judged, then the alarms decided with
        the winglet pair's coupled evidence set beside each other (:func:`partner_held`)."""
        seen = {u: self.observe(st, z, extra_variance, evidence) for u, st in states.items()}
        held = partner_held({u: o.level for u, o in seen.items()})
        return {u: self.decide(st, seen[u], held.get(u, ())) for u, st in states.items()}

    def decide(self, state: DetectionState, observation: Observation,
               held: Iterable[str] = ()) -> DetectionResult:
        """Latch the alarm if a feature reached ``alarm_confidence``; features in ``held``
        (evidence that belongs to another unit) do not raise it."""
        hold = set(held)
        conf = observation.confidence
        firing = [f for f, c in conf.items() if c >= self.alarm_confidence and f not in hold]
        new_alarm = bool(firing) and not state.alarm
        if new_alarm:
            state.alarm = True
            state.alarm_flight = state.n_flights
            state.alarm_features = firing
        return DetectionResult(conf, max(conf.values(), default=0.0), state.alarm, new_alarm,
                               list(state.alarm_features), observation.z_self,
                               observation.offset, sorted(hold & set(conf)))

    def to_dict(self) -> dict[str, Any]:
        self._check()
        return {"format": DETECTOR_FORMAT, "windows": list(self.windows),
                "alarm_confidence": self.alarm_confidence, "band_floor": self.band_floor,
                "false_alarm_rate": self.false_alarm_rate,
                "scale_quantile": self.scale_quantile, "directions": dict(self.directions),
                "pool_positions": self.pool_positions,
                "min_windows": dict(self.min_windows),
                "reference_flights": self.reference_flights,
                "window_clip": self.window_clip if math.isfinite(self.window_clip) else None,
                "median_from": self.median_from,
                "fleet_referenced": list(self.fleet_referenced),
                "within_std": self.within_std_.tolist(),
                "between_std": self.between_std_.tolist(),
                "evidence_variance": self.evidence_variance_.tolist(),
                "feature_names": list(self.feature_names_),
                "band": self.band_.tolist(),
                "healthy_scale": [[v if math.isfinite(v) else None for v in row]
                                  for row in self.healthy_scale_.tolist()],
                "n_healthy_flights": self.n_healthy_flights_.tolist()}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> FaultDetector:
        """A fitted detector from its document; an ``ema-detector/1`` one (bands the largest
        healthy ``|S_w|``, no rate) keeps its bands, with ``false_alarm_rate`` None."""
        if d.get("format") not in _DETECTOR_FORMATS:
            raise ValueError(f"not a {DETECTOR_FORMAT} document")
        legacy = d["format"] != DETECTOR_FORMAT
        det = cls(d["windows"], alarm_confidence=float(d["alarm_confidence"]),
                  band_floor=float(d["band_floor"]),
                  false_alarm_rate=float(d.get("false_alarm_rate")
                                         or DETECTION_DEFAULTS.false_alarm_rate),
                  scale_quantile=float(d.get("scale_quantile")
                                       or DETECTION_DEFAULTS.scale_quantile),
                  directions={k: int(v) for k, v in d.get("directions", {}).items()},
                  pool_positions=bool(d.get("pool_positions", False)),
                  min_windows={k: int(v) for k, v in d.get("min_windows", {}).items()},
                  reference_flights=int(d.get("reference_flights", 0)),
                  window_clip=math.inf if d.get("window_clip") is None
                  else float(d["window_clip"]),
                  median_from=int(d.get("median_from", 0)),
                  fleet_referenced=tuple(d.get("fleet_referenced", ())))
        det.feature_names_ = list(d["feature_names"])
        n = len(det.feature_names_)
        det.within_std_ = np.asarray(d.get("within_std", np.ones(n)), dtype=np.float64)
        det.between_std_ = np.asarray(d.get("between_std", np.zeros(n)), dtype=np.float64)
        # a document without it kept one scatter whatever a flight's evidence
        det.evidence_variance_ = np.asarray(d.get("evidence_variance", np.zeros(n)),
                                            dtype=np.float64)
        det.band_ = np.asarray(d["band"], dtype=np.float64).reshape(len(det.feature_names_),
                                                                    len(det.windows))
        scale = d.get("healthy_scale")
        det.healthy_scale_ = (np.full(det.band_.shape, np.nan) if scale is None else np.array(
            [[math.nan if v is None else float(v) for v in row] for row in scale],
            dtype=np.float64).reshape(det.band_.shape))
        if legacy:
            det.false_alarm_rate = None
        det.n_healthy_flights_ = np.asarray(d["n_healthy_flights"], dtype=np.int64)
        return det

