"""One flight through the chain for every actuator of an aircraft: detection, then (after an
alarm) classification, then (for a progressive mode) prognosis."""

from __future__ import annotations

import math
from collections.abc import Callable
from contextlib import AbstractContextManager, nullcontext
from dataclasses import dataclass, field
from datetime import datetime
from typing import Any

import numpy as np

from server.vocabulary import FAULT_MODES, GENERIC_FEATURES, OWN_FEATURE

from ..baselines import OutsideDesign
from ..classification.confirmation import CONFIRMATION, advance, advance_others
from ..classification.modes import modes_present
from ..detection import DetectionResult, update_units
from ..features import FlightFeatures
from ..prognosis import RulDistribution
from ..season import next_flights_per_day
from ..sensor_health import SensorJudgement
from .config import CHAIN
from .inputs import actuator_feature_names, classifier_vector, measurement_values, self_residuals
from .model import PhmModel
from .prognose import earliest, prognose_modes
from .state import ActuatorHealth

__all__ = ["MeasurementHook", "ActuatorOutcome", "analyze_flight"]

#: each mode's own feature's column in the classifier's input
OWN_COLUMN = {m: GENERIC_FEATURES.index(OWN_FEATURE[m]) for m in FAULT_MODES}
#: (position, measurement values) -> the values the prognosis sees: see :func:`analyze_flight`
MeasurementHook = Callable[[str, dict[str, float]], dict[str, float]]
#: times a named stage of the chain: ``with stage("prognosis"): ...``
StageTimer = Callable[[str], AbstractContextManager[object]]


def _untimed(_stage: str) -> AbstractContextManager[object]:
    return nullcontext()


@dataclass
class ActuatorOutcome:
    """What one flight said about one actuator."""

    flight_index: int
    features: dict[str, dict[str, float]]
    z: dict[str, float]
    confidence: dict[str, float]
    max_confidence: float
    alarm: bool
    new_alarm: bool
    alarm_features: list[str]
    class_probabilities: dict[str, float] | None
    fault_mode: str | None
    rul: RulDistribution | None = None
    #: the flight's sensor findings on this actuator's channels (SensorFinding.to_dict)
    sensor_findings: list[dict[str, Any]] = field(default_factory=list)
    #: this actuator's features not judged on the flight (an unusable channel)
    set_aside: list[str] = field(default_factory=list)
    #: features judged with a widened flight scatter (a noisier sensor): added variance
    widened: dict[str, float] = field(default_factory=dict)
    #: this actuator's conditions far outside the design's (OutsideDesign.to_dict): their
    #: features are in ``set_aside``
    outside_design: list[dict[str, Any]] = field(default_factory=list)
    #: while in alarm, the units it may belong to with their probabilities on this flight
    #: (``DetectionResult.isolation``)
    isolation: dict[str, float] = field(default_factory=dict)
    #: each mode's own probability of being present, pooled since the alarm (None: not
    #: classified, or a classifier without per-mode calibration)
    mode_probabilities: dict[str, float] | None = None
    #: the modes present, the leading one first (server.phm.classification.modes); empty
    #: when not classified
    modes: list[str] = field(default_factory=list)
    #: each mode's own feature in the classifier's input, pooled since the alarm (empty: not
    #: classified): a mode beyond the leading one's cross-talk is present too
    own_features: dict[str, float] = field(default_factory=dict)
    #: each progressive mode present's RUL; ``rul`` is the earliest of them (the unit's) and
    #: ``rul_mode`` its mode
    ruls: dict[str, RulDistribution] = field(default_factory=dict)
    rul_mode: str | None = None
    #: the mode the alarm's class was confirmed as on this flight (None: no confirmation
    #: now; server.phm.classification.confirmation)
    confirmed: str | None = None
    #: the modes beside the leading one confirmed present on this flight, and all so far
    confirmed_others: list[str] = field(default_factory=list)
    confirmed_modes: list[str] = field(default_factory=list)


def analyze_flight(model: PhmModel, features: FlightFeatures,
                   health: dict[str, ActuatorHealth], *, seed: int = 0,
                   flight_index: int | None = None, started_at: datetime | None = None,
                   base: str | None = None,
                   measurement_hook: MeasurementHook | None = None,
                   stage: StageTimer | None = None
                   ) -> dict[str, ActuatorOutcome]:
    """Advance every actuator's state by one flight (``health`` is updated in place).

    ``flight_index`` is the flight number of this flight when flights in between were not
    analysed (e.g. a campaign that renders every 20th flight): the particle filter then
    propagates over the gap. Default: ``flights_seen + 1`` (every flight analysed, the
    service's case). It must increase strictly from flight to flight.

    ``started_at`` (take-off time, timezone-aware) and ``base`` (the aircraft's home base)
    let the prognosis age thermal faults on the season's clock (:mod:`server.phm.season`);
    without them it counts flights.

    ``measurement_hook(position, values)`` may replace the values the prognosis of an
    actuator sees (and stores in its history) for an error-budget study: the evaluation's
    noise-free features (``hmsm evaluate --noise-free-features``). Never used in service.

    ``stage(name)`` (a context manager factory) times each actuator's classification and
    prognosis as the stages "classification" and "prognosis": the service's stage durations
    (``server.timing.StageClock.stage``). None: untimed.
    """
    timed = stage or _untimed
    z_all = model.baseline.zscores(features)
    evidence = model.baseline.evidence_weights(features)
    judged = _judge_sensors(model, features, z_all, evidence)
    if judged is not None:
        z_all = judged.z
    outside = model.baseline.outside_design(features)
    z_all = _set_aside_outside(z_all, outside)
    index_of: dict[str, int] = {}
    for position, h in health.items():
        index_of[position] = _advance(h, flight_index)
        _track_calendar(h, index_of[position], started_at)
    detected = update_units(
        model.detector, {p: h.detection for p, h in health.items()}, z_all,
        None if judged is None else judged.extra_variance, evidence)
    out: dict[str, ActuatorOutcome] = {}
    for position, h in health.items():
        index, det = index_of[position], detected[position]
        if det.new_alarm:
            h.alarm_index = index
        generic = measurement_values(self_residuals(model.baseline, z_all, det), position)
        if measurement_hook is not None:
            generic = measurement_hook(position, generic)
        h.history.append((index, generic))
        del h.history[:-CHAIN.history_flights]
        with timed("classification"):
            lead = h.fault_mode  # the last classified flight's leading mode
            probs = _classify(model, h, position) if det.alarm else None
            own, beyond = _name_modes(model, h) if probs else (None, [])
            confirmed = _confirm(h, lead, probs)
            others = _confirm_others(h, own or {}, beyond) if probs else []
        with timed("prognosis"):
            ruls = (prognose_modes(model, h, generic, position, index, base=base, seed=seed)
                    if det.alarm else {})
        rul_mode, rul = earliest(ruls)
        out[position] = _outcome(features, z_all, det, h, position, index, probs, rul)
        out[position].confirmed = confirmed
        out[position].ruls, out[position].rul_mode = ruls, rul_mode
        if probs:
            out[position].mode_probabilities = own
            out[position].own_features = pooled_own_features(h)
            out[position].modes = list(h.modes)
            out[position].confirmed_others = others
            out[position].confirmed_modes = list(h.confirmed_modes)
        if judged is not None:
            _note_sensors(out[position], judged, position)
        _note_outside(out[position], outside, position)
    return out


def _set_aside_outside(z: dict[str, float], outside: list[OutsideDesign]) -> dict[str, float]:
    """The residuals with the features of conditions outside the design not judged (NaN)."""
    names = {n for o in outside for n in o.features}
    return {n: math.nan if n in names else v for n, v in z.items()} if names else z


def _note_outside(out: ActuatorOutcome, outside: list[OutsideDesign], position: str) -> None:
    mine = [o for o in outside if o.position == position]
    out.outside_design = [o.to_dict() for o in mine]
    out.set_aside += [n for o in mine for n in o.features if n not in out.set_aside]


def _judge_sensors(model: PhmModel, features: FlightFeatures, z: dict[str, float],
                   evidence: dict[str, float]) -> SensorJudgement | None:
    """The flight's residuals judged with its sensors' findings (None: no sensor model, or
    features stored without their signal-quality figures)."""
    if model.sensors is None or not features.quality:
        return None
    return model.sensors.judge(features.quality, z, evidence)


def _note_sensors(out: ActuatorOutcome, judged: SensorJudgement, position: str) -> None:
    names = set(actuator_feature_names(position))
    out.sensor_findings = [f.to_dict() for f in judged.for_position(position)]
    out.set_aside = [n for n in judged.set_aside if n in names]
    out.widened = {n: v for n, v in judged.extra_variance.items() if n in names}


def _advance(h: ActuatorHealth, flight_index: int | None) -> int:
    """This flight's index for the actuator: the next one, or the caller's (after a gap)."""
    if flight_index is None:
        h.flights_seen += 1
    else:
        if h.history and int(flight_index) <= h.history[-1][0]:
            raise ValueError(f"flight_index must increase: {flight_index} after "
                             f"{h.history[-1][0]}")
        h.flights_seen = int(flight_index)
    return h.flights_seen


def _track_calendar(h: ActuatorHealth, index: int, started_at: datetime | None) -> None:
    """Update the aircraft's flying rate from the take-off times of analysed flights."""
    if started_at is None:
        return
    if h.last_started_at is not None and h.history:
        h.flights_per_day = next_flights_per_day(
            h.flights_per_day, index - h.history[-1][0],
            started_at - datetime.fromisoformat(h.last_started_at))
    h.last_started_at = started_at.isoformat()


def _classify(model: PhmModel, h: ActuatorHealth, position: str) -> dict[str, float] | None:
    """Class probabilities from the class evidence accumulated since the alarm (older flights
    decayed); the leading mode's filter, if it had one as a mode present beside the previous
    leader (:func:`_name_modes`, chain.prognose), carries on.

    The flights since the alarm are not independent views of the fault: their features are
    windowed over several flights and one fault drives them all. Multiplying their calibrated
    probabilities would claim certainty after a handful of flights (100.0 %, on a false alarm
    too), so the evidence is pooled as the weighted mean of the flights' log-probabilities, a
    weighted geometric mean of calibrated single-flight probabilities; the classifier's error
    floor is then applied to the pooled probabilities (shown, never 100 %). The decision (the
    leading mode) is that of the summed raw evidence either way."""
    if model.classifier is None:
        return None
    vector = classifier_vector(h.detection, position)[np.newaxis, :]
    logp = model.classifier.raw_log_proba(vector)[0]
    classes = [str(c) for c in model.classifier.classes_.tolist()]
    decision = model.classifier.decision_function(vector)[0]
    acc = _decayed(h.class_log_prob, classes, logp)
    if h.class_weight is None:  # a state stored before the weight was kept: saturated
        h.class_weight = 0.0 if h.class_log_prob is None else 1.0 / (
            1.0 - CHAIN.class_evidence_decay)
    if h.mode_decision is None and h.class_log_prob is not None:
        # a state stored before the decision values were kept: its past flights taken as
        # this one, so the pooled mean starts at this flight's values
        h.mode_decision = {c: h.class_weight * float(v)
                           for c, v in zip(classes, decision, strict=True)}
    h.mode_decision = _decayed(h.mode_decision, classes, decision)
    _pool_own_features(h, vector[0])
    h.class_log_prob = acc
    h.class_weight = CHAIN.class_evidence_decay * h.class_weight + 1.0
    pooled = {c: v / h.class_weight for c, v in acc.items()}
    top = max(pooled.values())
    weights = {c: math.exp(v - top) for c, v in pooled.items()}
    total = sum(weights.values())
    # the floor on what is shown, after pooling: the decision stays the summed evidence's
    floored = model.classifier.apply_error_floor(np.array([weights[c] / total for c in classes]))
    probs = {c: float(p) for c, p in zip(classes, floored, strict=True)}
    mode = max(probs, key=lambda c: probs[c])
    h.fault_mode = mode  # its filter, if it had one as a mode present, carries on
    return probs


def _name_modes(model: PhmModel, h: ActuatorHealth
                ) -> tuple[dict[str, float] | None, list[str]]:
    """Set the modes present (``h.modes``: the leading one, every other at the mode-set
    threshold and every one beyond the leading mode's cross-talk) and return each mode's own
    probability (None without per-mode calibration: the leading mode alone) and the modes
    beyond the cross-talk."""
    own = _own_probabilities(model, h)
    lead = str(h.fault_mode)
    if own is None:
        h.modes = [lead]
        return None, []
    beyond = ([] if model.crosstalk is None
              else model.crosstalk.beyond(lead, pooled_own_features(h)))
    h.modes = modes_present(lead, own, beyond=beyond)
    return own, beyond


def pooled_own_features(h: ActuatorHealth) -> dict[str, float]:
    """Each mode's own feature pooled over the flights since the alarm (their decayed mean);
    empty before the first classified flight."""
    if not h.own_feature or not h.class_weight:
        return {}
    return {m: v / h.class_weight for m, v in h.own_feature.items()}


def _pool_own_features(h: ActuatorHealth, vector: np.ndarray) -> None:
    """Add this flight's own feature of each mode to their decayed sums (before the flight's
    weight joins ``class_weight``, as the decision values are)."""
    values = [float(vector[OWN_COLUMN[m]]) for m in FAULT_MODES]
    if h.own_feature is None and h.class_log_prob is not None:
        # a state stored before the own features were kept: its past flights taken as this one
        h.own_feature = {m: (h.class_weight or 0.0) * v
                         for m, v in zip(FAULT_MODES, values, strict=True)}
    h.own_feature = _decayed(h.own_feature, list(FAULT_MODES), np.asarray(values))


def _decayed(acc: dict[str, float] | None, classes: list[str], values: np.ndarray
             ) -> dict[str, float]:
    """``acc`` decayed by one flight, plus this flight's ``values`` (one per class)."""
    acc = acc or {}
    return {c: CHAIN.class_evidence_decay * acc.get(c, 0.0) + float(v)
            for c, v in zip(classes, values, strict=True)}


def _own_probabilities(model: PhmModel, h: ActuatorHealth) -> dict[str, float] | None:
    """Each mode's own probability of being present, from its decision values pooled over the
    flights since the alarm (their decayed mean); None without per-mode calibration."""
    clf = model.classifier
    if (clf is None or clf.mode_calibration_ is None
            or not h.mode_decision or not h.class_weight):
        return None
    classes = [str(c) for c in clf.classes_.tolist()]
    mean = np.array([h.mode_decision.get(c, 0.0) for c in classes]) / h.class_weight
    return {c: float(q) for c, q in
            zip(classes, clf.mode_proba_from_decision(mean[np.newaxis, :])[0], strict=True)}


def _confirm(h: ActuatorHealth, lead: str | None, probs: dict[str, float] | None
             ) -> str | None:
    """Advance the confirmation rule on a classified flight (``lead``: the previous one's
    leading mode); the mode it confirms on this flight (once per alarm), else None."""
    if not probs or h.confirmed_mode is not None:
        return None
    mode, h.class_run, held = advance(CONFIRMATION, lead, h.class_run, probs)
    if held:
        h.confirmed_mode = mode
        return mode
    return None


def _confirm_others(h: ActuatorHealth, own: dict[str, float], beyond: list[str]
                    ) -> list[str]:
    """Advance the confirmation of the modes beside the leading one; those it confirms on this
    flight (each once per alarm: a mode confirmed as the alarm's class is not again)."""
    h.mode_runs, held = advance_others(CONFIRMATION, h.mode_runs, h.modes, own, beyond)
    now = [m for m in held if m not in h.confirmed_modes and m != h.confirmed_mode]
    h.confirmed_modes += now
    return now


def _finite(v: float) -> float | None:
    return float(v) if v is not None and math.isfinite(v) else None


def _outcome(features: FlightFeatures, z_all: dict[str, float], det: DetectionResult,
             h: ActuatorHealth, position: str, index: int,
             probs: dict[str, float] | None, rul: RulDistribution | None) -> ActuatorOutcome:
    names = actuator_feature_names(position)
    return ActuatorOutcome(
        flight_index=index,
        features={n: features.summaries[n].to_dict() for n in names if n in features.summaries},
        z={n: v for n in names if (v := _finite(z_all.get(n, math.nan))) is not None},
        confidence=dict(det.confidence), max_confidence=float(det.max_confidence),
        alarm=det.alarm, new_alarm=det.new_alarm, alarm_features=list(det.alarm_features),
        class_probabilities=probs, fault_mode=h.fault_mode if det.alarm else None, rul=rul,
        isolation=dict(det.isolation))
