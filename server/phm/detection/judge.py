"""The online judge: one flight of an aircraft's monitored units at a time
(:func:`update_units`), as the chain, training and the evaluation run it.

Running distribution and separation confidence: for each feature the unit's state keeps the
self-referenced residuals (:mod:`.statistics`) of the last ``max(windows)`` flights with a
valid value. For each window length ``w`` the running mean of the last ``n = min(w,
available)`` residuals, scaled to unit variance, is ``S_w = sqrt(n) mean(z)``; a window is
judged once it holds ``w`` residuals (its band is a full window's). Because ``S_w`` has unit
standard error, the confidence that the running mean lies outside the healthy band ``b_w``
(:mod:`.detector`) is

    c_w = Phi(d S_w - b_w),      c = max over the judged windows of c_w  in [0, 1],

``d`` the fault's direction (``|S_w|`` for a two-sided feature). Residuals beyond
``window_clip`` enter the windows longer than one flight clipped to it (a single odd flight
moves ``S_3`` by at most ``window_clip / sqrt(3)``, a sustained drift not at all); windows of
``median_from`` flights or more use the running median, ``S_w = sqrt(n / (pi/2)) median``
(unit variance on healthy flights too, unmoved by a minority of odd flights). The one-flight
window keeps the raw value, for step faults.

The unit alarms when ``c`` of one of its features reaches ``alarm_confidence``, unless the
winglet pair's rule (:mod:`.pair`) leaves that feature's evidence to the partner drive: every
unit of the flight is observed first, then the alarms are decided. An alarm names the units it
may belong to with their probabilities (``DetectionResult.isolation``, on every flight it
stands, from that flight's levels): its own unit alone, or both winglet drives when it rests on
a coupled feature alone (:func:`.pair.isolation_of`).
The alarm latches until maintenance: a replaced actuator gets a fresh state
(:meth:`DetectionState.reset`).

:mod:`.sequences` is this judge vectorised over flight sequences; the two are held equal by
``tests/phm/test_judge.py``.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import replace

import numpy as np
from scipy.special import ndtr

from .config import UNITS, unit_features
from .detector import FaultDetector
from .pair import is_pair_coupled, isolation_of, pair_level, partner_held
from .state import DetectionResult, DetectionState, Observation
from .statistics import median_n_eff, reference_posterior

__all__ = ["decide", "new_state", "new_states", "observe", "update_units"]


def new_state(detector: FaultDetector, unit: str) -> DetectionState:
    """A fresh state of ``unit`` over the detector's features of it."""
    detector.check_fitted()
    return DetectionState.new(unit, unit_features(unit, detector.feature_names_))


def new_states(detector: FaultDetector, units: Iterable[str] = UNITS
               ) -> dict[str, DetectionState]:
    """Fresh states of an aircraft's units."""
    return {u: new_state(detector, u) for u in units}


def update_units(detector: FaultDetector, states: Mapping[str, DetectionState],
                 z: Mapping[str, float], extra_variance: Mapping[str, float] | None = None,
                 evidence: Mapping[str, float] | None = None) -> dict[str, DetectionResult]:
    """One flight of the units of an aircraft (``states``, advanced in place): each observed,
    then the alarms decided with the winglet pair's coupled evidence left to the drive that
    has moved further (:func:`~server.phm.detection.pair.partner_held`). A unit judged
    without its partner holds nothing.

    ``z``: the flight's standardised residuals by feature name; ``extra_variance`` (feature ->
    variance in residual units) widens a feature's flight scatter for this flight, the share a
    sensor measured noisier than in design adds (:mod:`server.phm.sensor_health`);
    ``evidence`` (feature -> evidence weight, :mod:`.evidence`) adds the flight's sampling
    share."""
    seen = {u: observe(detector, st, z, extra_variance, evidence) for u, st in states.items()}
    levels = {u: o.level for u, o in seen.items()}
    held = partner_held(levels)
    out = {u: decide(detector, st, seen[u], held.get(u, ())) for u, st in states.items()}
    counts = {u: {f: len(st.history.get(f, ())) for f in seen[u].level}
              for u, st in states.items()}
    return {u: replace(r, isolation=isolation_of(u, r.alarm_features, levels, counts))
            if r.alarm else r for u, r in out.items()}


def observe(detector: FaultDetector, state: DetectionState, z: Mapping[str, float],
            extra_variance: Mapping[str, float] | None = None,
            evidence: Mapping[str, float] | None = None) -> Observation:
    """Add one flight's residuals to one unit's ``state`` (in place) and judge every feature,
    without deciding the alarm (:func:`update_units` does, the pair seen together)."""
    detector.check_fitted()
    extra = detector.flight_variance(evidence, extra_variance)
    keep = max(detector.windows)
    margin: dict[str, float] = {}
    level: dict[str, float] = {}
    z_self: dict[str, float] = {}
    offset: dict[str, float] = {}
    for f in state.features:
        hist = state.history.setdefault(f, [])
        ref = state.reference.setdefault(f, [])
        i = detector.feature_names_.index(f)
        v = z.get(f, math.nan)
        if v is not None and math.isfinite(v):
            z_self[f], offset[f] = _self_referenced(detector, ref, i, float(v),
                                                    extra.get(f, 0.0))
            if len(ref) < detector.reference_flights:
                ref.append(float(v))
            hist.append(z_self[f])
            del hist[:-keep]
        margin[f] = _margin(detector, f, i, hist)
        if is_pair_coupled(f):  # only the pair rule reads it
            level[f] = pair_level(hist, detector.direction(f))
    state.n_flights += 1
    state.confidence = {f: float(ndtr(m)) for f, m in margin.items()}
    return Observation(dict(state.confidence), level, z_self, offset)


def decide(detector: FaultDetector, state: DetectionState, observation: Observation,
           held: Iterable[str] = ()) -> DetectionResult:
    """Latch the alarm if a feature reached ``alarm_confidence``; features in ``held``
    (evidence that belongs to another unit) do not raise it."""
    hold = set(held)
    conf = observation.confidence
    firing = [f for f, c in conf.items() if c >= detector.alarm_confidence and f not in hold]
    new_alarm = bool(firing) and not state.alarm
    if new_alarm:
        state.alarm = True
        state.alarm_flight = state.n_flights
        state.alarm_features = firing
    return DetectionResult(conf, max(conf.values(), default=0.0), state.alarm, new_alarm,
                           list(state.alarm_features), observation.z_self,
                           observation.offset, sorted(hold & set(conf)))


def _self_referenced(detector: FaultDetector, ref: Sequence[float], i: int, v: float,
                     extra_variance: float = 0.0) -> tuple[float, float]:
    """``(z_self, u_hat)`` of one value of feature ``i`` against the unit's reference
    residuals ``ref``; ``extra_variance`` adds to the flight scatter."""
    med = float(np.median(ref)) if ref else 0.0
    u_hat, sd = reference_posterior(np.array(med), np.array(len(ref)),
                                    detector.within_std_[i], detector.between_std_[i])
    return (v - float(u_hat)) / math.sqrt(float(sd) ** 2 + extra_variance), float(u_hat)


def _margin(detector: FaultDetector, f: str, i: int, hist: list[float]) -> float:
    """How far the feature's running statistic stands beyond its band, the largest over
    the judged windows [standard error]; -inf with no window judged."""
    d = detector.direction(f)
    min_w = detector.min_window(f)
    best = -math.inf
    for k, w in enumerate(detector.windows):
        if len(hist) < max(w, min_w):
            break  # a window is judged once it is full (its band is a full one's)
        if w < min_w:
            continue
        last = hist[-w:]
        if w > 1:
            last = [min(max(x, -detector.window_clip), detector.window_clip) for x in last]
        if detector.uses_median(w):
            s = float(np.median(last)) * math.sqrt(float(median_n_eff(len(last))))
        else:
            s = sum(last) / math.sqrt(len(last))
        s = abs(s) if d == 0 else d * s
        best = max(best, s - float(detector.band_[i, k]))
    return best
