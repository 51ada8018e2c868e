"""The PHM chain of one actuator, flight by flight, as the service runs it (paper Figure 15).

features (whole aircraft) -> standardised residuals z -> detection per actuator, against the
actuator's own reference (self-referenced residuals, :mod:`server.phm.detection`) -> after an
alarm: classification of the self-referenced residuals of the last three flights (class
log-probabilities accumulated since the alarm) -> for a progressive mode: particle-filter
prognosis on the mode's measurement feature, a physical-unit residual with the actuator's own
offset removed.

Units and time base: one step per flight; ``flight_index`` counts the flights an actuator has
seen since installation. Severity is normalised (failure threshold 1.0).

Monitored units: each actuator carries its own six features; the winglet actuators also carry
the pair's ``WL.F_REWEAR`` (rod-end wear cannot be told apart between the two rod ends from the
two LVDTs alone, so both winglet actuators alarm on it). The classifier sees the seven generic
features of the alarmed actuator (``F_REWEAR`` = 0 for the wingtip).

Everything persists as JSON: :class:`PhmModel` (trained, in a model version) and
:class:`ActuatorHealth` (state per actuator, between flights). Never pickle.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from datetime import datetime
from typing import Any

import numpy as np

from .baselines import FleetBaseline
from .classification import FaultClassifier
from .detection import DetectionResult, DetectionState, FaultDetector
from .features import FlightFeatures
from .prognosis import (
    MeasurementModel,
    ParticleFilterPrognoser,
    PrognoserConfig,
    PrognoserState,
    RulDistribution,
    growth_onset,
)
from .season import SeasonalClimate, StressClock, next_flights_per_day

__all__ = [
    "MODEL_FORMAT",
    "HEALTH_FORMAT",
    "MeasurementHook",
    "PROGRESSIVE",
    "GENERIC_FEATURES",
    "actuator_feature_names",
    "classifier_vector",
    "measurement_values",
    "self_residuals",
    "OWN_FEATURE",
    "CLASS_EVIDENCE_DECAY",
    "MeasurementSpec",
    "surface_of",
    "PhmModel",
    "ActuatorHealth",
    "ActuatorOutcome",
    "analyze_flight",
]

#: /5: thermal modes age on the season's stress clock (the model carries the bases' climate);
#: /4: features/5 (F_MTEL is the screw's friction ratio from the cruise torque hysteresis, and
#: grows with its fault); /3: features/4 (F_MTWEAR is the screw gap between flanks); /2 added
#: self-referenced detection and classifier input (3-flight means). An older model would be fed
#: inputs it was not trained on
MODEL_FORMAT = "ema-phm-model/5"
#: formats of older chains: their baselines were fitted on other feature definitions
#: (/2: F_MTWEAR was the reversal lost motion, features/3; /3: F_MTEL was the ratio of apparent
#: efficiencies, falling with its fault, features/4), so they are refused, not misread
_OLD_MODEL_FORMATS = ("ema-phm-model/1", "ema-phm-model/2", "ema-phm-model/3",
                      "ema-phm-model/4")
HEALTH_FORMAT = "ema-actuator-health/2"
#: (position, measurement values) -> the values the prognosis sees: see :func:`analyze_flight`
MeasurementHook = Callable[[str, dict[str, float]], dict[str, float]]
PROGRESSIVE = ("TTS", "DMD", "MTEL", "MTWEAR", "REWEAR")
#: the paper's Table 1: one preferential feature per failure mode (tracked by the filter)
OWN_FEATURE = {"TTS": "F_TTS", "DMD": "F_DMD", "SE": "F_SE", "BDO": "F_BDO", "MTEL": "F_MTEL",
               "MTWEAR": "F_MTWEAR", "REWEAR": "F_REWEAR"}
#: weight of the older flights' class evidence per flight (recent flights, at a larger
#: severity, are more telling; 0.8 keeps about five flights of memory)
CLASS_EVIDENCE_DECAY = 0.8
GENERIC_FEATURES = ("F_TTS", "F_DMD", "F_SE", "F_BDO", "F_MTEL", "F_MTWEAR", "F_REWEAR")
_HISTORY_FLIGHTS = 600  # flights of residuals kept for a filter replay
CLASSIFIER_FLIGHTS = 3  # valid flights averaged into the classifier's input


def actuator_feature_names(position: str) -> list[str]:
    """Aircraft feature names monitored for one actuator position."""
    names = [f"{position}.{g}" for g in GENERIC_FEATURES if g != "F_REWEAR"]
    if position in ("WL1", "WL2"):
        names.append("WL.F_REWEAR")
    return names


def _generic(name: str) -> str:
    return name.split(".", 1)[1]


def classifier_vector(detection: DetectionState, position: str) -> np.ndarray:
    """The classifier's input for an actuator: per generic feature, the mean self-referenced
    residual of its last ``CLASSIFIER_FLIGHTS`` valid flights (the detection history),
    compressed as ``sign(x) log(1 + |x|)``; missing features count as 0.

    The short mean bridges flights on which an intermittent signature does not show (backlash
    only shows on flights whose load changes sign); the compression lets the linear SVM weigh
    *which* features left their band rather than by how much (residuals span 0 to 100+).
    On design seed 1 (held-out 30 %) these two took the accuracy from 93 % to 99 %.
    """
    out = np.zeros(len(GENERIC_FEATURES))
    for name in actuator_feature_names(position):
        hist = detection.history.get(name) or []
        if hist:
            v = float(np.mean(hist[-CLASSIFIER_FLIGHTS:]))
            out[GENERIC_FEATURES.index(_generic(name))] = math.copysign(math.log1p(abs(v)), v)
    return out


def measurement_values(residuals: Mapping[str, float], position: str) -> dict[str, float]:
    """Physical-unit residuals of an actuator's features by generic name (finite ones only)."""
    out = {}
    for name in actuator_feature_names(position):
        v = residuals.get(name, math.nan)
        if v is not None and math.isfinite(v):
            out[_generic(name)] = float(v)
    return out


def self_residuals(baseline: FleetBaseline, z: Mapping[str, float],
                   det: DetectionResult) -> dict[str, float]:
    """Physical-unit residuals with the actuator's own offset (learned by detection from its
    reference flights) removed: what the particle filter measures."""
    return baseline.to_physical({n: v - det.offset[n] for n, v in z.items()
                                 if n in det.offset})


@dataclass(frozen=True)
class MeasurementSpec:
    """Which generic feature tracks a progressive mode, how it depends on severity, and the
    mode's filter configuration (first-trial degradation parameters from the design runs)."""

    feature: str
    model: MeasurementModel
    prognoser: PrognoserConfig | None = None
    #: surface-specific models ("WL" for the winglet pair, "WT" for the wingtip) where the
    #: design runs had enough flights: the same wear shows differently on a drive that shares
    #: its surface with a second drive than on a lone one
    by_surface: dict[str, MeasurementModel] = field(default_factory=dict)
    #: temperature sensitivity of the mode's ageing [1/K] and its reference temperature
    #: [degC]: the filter's clock adds exp(beta (T - T_ref)) per flight (server.phm.season);
    #: beta = 0 is a flight clock; T_ref None is each base's own annual mean
    stress_beta_per_k: float = 0.0
    stress_ref_c: float | None = None
    #: replay the filter from the growth's estimated onset (:func:`growth_onset` on the stored
    #: history) instead of from the alarm: for faults that grow along a straight line (wear),
    #: whose flights between onset and alarm already carry the rate
    replay_from_onset: bool = False
    #: surface-specific filters where the design runs showed the degradation law differs by
    #: surface (winglet wear slows down as the partner drive takes the load)
    prognoser_by_surface: dict[str, PrognoserConfig] = field(default_factory=dict)

    def model_for(self, position: str) -> MeasurementModel:
        return self.by_surface.get(surface_of(position), self.model)

    def config_for(self, position: str) -> PrognoserConfig | None:
        return self.prognoser_by_surface.get(surface_of(position), self.prognoser)

    def to_dict(self) -> dict[str, Any]:
        return {"feature": self.feature, "model": self.model.to_dict(),
                "prognoser": None if self.prognoser is None else self.prognoser.to_dict(),
                "by_surface": {k: m.to_dict() for k, m in self.by_surface.items()},
                "stress_beta_per_k": self.stress_beta_per_k, "stress_ref_c": self.stress_ref_c,
                "replay_from_onset": self.replay_from_onset,
                "prognoser_by_surface": {k: c.to_dict()
                                         for k, c in self.prognoser_by_surface.items()}}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> MeasurementSpec:
        cfg = d.get("prognoser")
        return cls(str(d["feature"]), MeasurementModel.from_dict(dict(d["model"])),
                   None if cfg is None else PrognoserConfig.from_dict(dict(cfg)),
                   {k: MeasurementModel.from_dict(dict(m))
                    for k, m in (d.get("by_surface") or {}).items()},
                   float(d.get("stress_beta_per_k", 0.0)),
                   None if d.get("stress_ref_c") is None else float(d["stress_ref_c"]),
                   bool(d.get("replay_from_onset", False)),
                   {k: PrognoserConfig.from_dict(dict(c))
                    for k, c in (d.get("prognoser_by_surface") or {}).items()})


def surface_of(position: str) -> str:
    """``WL`` for the winglet drives, ``WT`` for the wingtip drive."""
    return "WT" if position == "WT" else "WL"


@dataclass
class PhmModel:
    """Everything the chain needs at run time, fitted on a design campaign."""

    baseline: FleetBaseline
    detector: FaultDetector
    classifier: FaultClassifier | None
    measurement: dict[str, MeasurementSpec]
    prognoser: PrognoserConfig = field(default_factory=PrognoserConfig)
    #: annual temperature cycle of each base (the stress clock's temperatures); None: flights
    climate: SeasonalClimate | None = None

    def to_dict(self) -> dict[str, Any]:
        return {"format": MODEL_FORMAT, "baseline": self.baseline.to_dict(),
                "detector": self.detector.to_dict(),
                "classifier": None if self.classifier is None else self.classifier.to_dict(),
                "measurement": {m: s.to_dict() for m, s in self.measurement.items()},
                "prognoser": self.prognoser.to_dict(),
                "climate": None if self.climate is None else self.climate.to_dict()}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> PhmModel:
        if d.get("format") in _OLD_MODEL_FORMATS:
            raise ValueError(f"this model version was trained by an older chain "
                             f"({d.get('format')}); train a new one (hmsm train)")
        if d.get("format") != MODEL_FORMAT:
            raise ValueError(f"not a {MODEL_FORMAT} document")
        clf = d.get("classifier")
        return cls(FleetBaseline.from_dict(d["baseline"]), FaultDetector.from_dict(d["detector"]),
                   None if clf is None else FaultClassifier.from_dict(clf),
                   {m: MeasurementSpec.from_dict(s) for m, s in d["measurement"].items()},
                   PrognoserConfig.from_dict(dict(d["prognoser"])),
                   None if d.get("climate") is None else SeasonalClimate.from_dict(d["climate"]))

    def new_health(self, position: str) -> ActuatorHealth:
        known = set(self.detector.feature_names_)
        feats = [f for f in actuator_feature_names(position) if f in known]
        return ActuatorHealth(position=position, detection=DetectionState.new(position, feats))


@dataclass
class ActuatorHealth:
    """State of one actuator carried between flights (JSON)."""

    position: str
    detection: DetectionState
    flights_seen: int = 0
    #: flight index of the first alarm: the filter starts there (the fault was not known
    #: before; replaying the healthy flights since installation drags the tuned law down)
    alarm_index: int | None = None
    class_log_prob: dict[str, float] | None = None
    fault_mode: str | None = None
    prognosis: dict[str, Any] | None = None
    history: list[tuple[int, dict[str, float]]] = field(default_factory=list)
    #: take-off time (ISO 8601) of the last flight analysed and the aircraft's flying rate
    #: [flight/day], for the stress clock (server.phm.season)
    last_started_at: str | None = None
    flights_per_day: float | None = None

    def to_dict(self) -> dict[str, Any]:
        return {"format": HEALTH_FORMAT, "position": self.position,
                "detection": self.detection.to_dict(), "flights_seen": self.flights_seen,
                "alarm_index": self.alarm_index,
                "class_log_prob": self.class_log_prob, "fault_mode": self.fault_mode,
                "prognosis": self.prognosis,
                "history": [[i, z] for i, z in self.history],
                "last_started_at": self.last_started_at,
                "flights_per_day": self.flights_per_day}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> ActuatorHealth:
        if d.get("format") not in (HEALTH_FORMAT, "ema-actuator-health/1"):
            raise ValueError(f"not a {HEALTH_FORMAT} document")
        # version 1 kept standardised residuals in the history; they cannot seed a filter that
        # now tracks physical residuals, so that history is dropped (detection state is kept)
        keep_history = d.get("format") == HEALTH_FORMAT
        return cls(position=str(d["position"]),
                   detection=DetectionState.from_dict(d["detection"]),
                   flights_seen=int(d["flights_seen"]),
                   alarm_index=None if d.get("alarm_index") is None else int(d["alarm_index"]),
                   class_log_prob=d.get("class_log_prob"), fault_mode=d.get("fault_mode"),
                   prognosis=d.get("prognosis"),
                   history=[(int(i), {k: float(v) for k, v in z.items()})
                            for i, z in d.get("history", [])] if keep_history else [],
                   last_started_at=d.get("last_started_at"),
                   flights_per_day=None if d.get("flights_per_day") is None
                   else float(d["flights_per_day"]))


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


def _finite(v: float) -> float | None:
    return float(v) if v is not None and math.isfinite(v) else None


def _replay(model: PhmModel, mode: str, position: str,
            history: list[tuple[int, dict[str, float]]], seed: int,
            clock: StressClock | None) -> PrognoserState | None:
    spec = model.measurement.get(mode)
    if spec is None:
        return None
    config = spec.config_for(position) or model.prognoser
    pf = ParticleFilterPrognoser(config, spec.model_for(position))
    state = ParticleFilterPrognoser.initial_state(config, spec.model_for(position), seed)
    for index, z in history:
        value = z.get(spec.feature)
        if value is not None and math.isfinite(value):
            state = pf.update(state, value, index, stress=_stress(clock, state, index))
    return state


def _growth_onset(spec: MeasurementSpec, position: str,
                  history: list[tuple[int, dict[str, float]]]) -> int:
    """The flight at which the mode's fault began to grow, from the inverted measurements of
    the actuator's stored history (:func:`~server.phm.prognosis.onset.growth_onset`)."""
    points = [(i, z[spec.feature]) for i, z in history
              if spec.feature in z and math.isfinite(z[spec.feature])]
    if not points:
        return history[-1][0] if history else 0
    severity = spec.model_for(position).invert(np.array([v for _, v in points]))
    return growth_onset([i for i, _ in points], severity)


def _stress_clock(model: PhmModel, spec: MeasurementSpec, h: ActuatorHealth, base: str | None,
                  index: int) -> StressClock | None:
    """The mode's stress clock for this aircraft, anchored at the current flight; None (a
    flight clock) for a mode without temperature sensitivity, an unknown base or date."""
    if (spec.stress_beta_per_k == 0.0 or model.climate is None or not model.climate.knows(base)
            or h.last_started_at is None or not h.flights_per_day):
        return None
    return StressClock(model.climate, str(base), spec.stress_beta_per_k, spec.stress_ref_c,
                       datetime.fromisoformat(h.last_started_at), index, h.flights_per_day)


def _stress(clock: StressClock | None, state: PrognoserState, index: int) -> float | None:
    if clock is None or state.flight_index is None:
        return None
    return clock.between(state.flight_index, index)


def _track_calendar(h: ActuatorHealth, index: int, started_at: datetime | None) -> None:
    """Update the aircraft's flying rate from the take-off times of analysed flights."""
    if started_at is None:
        return
    if h.last_started_at is not None and h.history:
        h.flights_per_day = next_flights_per_day(
            h.flights_per_day, index - h.history[-1][0],
            started_at - datetime.fromisoformat(h.last_started_at))
    h.last_started_at = started_at.isoformat()


def _predict(pf: ParticleFilterPrognoser, state: PrognoserState, index: int,
             clock: StressClock | None) -> RulDistribution:
    if clock is None or state.flight_index is None:
        return pf.predict(state, at_flight=index)
    curve = clock.curve(state.flight_index, pf.config.max_horizon_flights)
    return pf.predict(state, at_flight=index, stress_curve=curve)


def analyze_flight(model: PhmModel, features: FlightFeatures,
                   health: dict[str, ActuatorHealth], *, seed: int = 0,
                   flight_index: int | None = None, started_at: datetime | None = None,
                   base: str | None = None,
                   measurement_hook: MeasurementHook | None = None
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
    """
    z_all = model.baseline.zscores(features)
    out: dict[str, ActuatorOutcome] = {}
    for position, h in health.items():
        if flight_index is None:
            h.flights_seen += 1
        else:
            if h.history and int(flight_index) <= h.history[-1][0]:
                raise ValueError(f"flight_index must increase: {flight_index} after "
                                 f"{h.history[-1][0]}")
            h.flights_seen = int(flight_index)
        index = h.flights_seen
        _track_calendar(h, index, started_at)
        det = model.detector.update(h.detection, z_all)
        if det.new_alarm:
            h.alarm_index = index
        generic = measurement_values(self_residuals(model.baseline, z_all, det), position)
        if measurement_hook is not None:
            generic = measurement_hook(position, generic)
        h.history.append((index, generic))
        del h.history[:-_HISTORY_FLIGHTS]

        probs = None
        if det.alarm and model.classifier is not None:
            logp = model.classifier.predict_log_proba(
                classifier_vector(h.detection, position)[np.newaxis, :])[0]
            classes = [str(c) for c in model.classifier.classes_.tolist()]
            acc = h.class_log_prob or dict.fromkeys(classes, 0.0)
            acc = {c: CLASS_EVIDENCE_DECAY * acc.get(c, 0.0) + float(lp)
                   for c, lp in zip(classes, logp, strict=True)}
            h.class_log_prob = acc
            top = max(acc.values())
            weights = {c: math.exp(v - top) for c, v in acc.items()}
            total = sum(weights.values())
            probs = {c: w / total for c, w in weights.items()}
            mode = max(probs, key=lambda c: probs[c])
            if mode != h.fault_mode:
                h.fault_mode = mode
                h.prognosis = None  # the filter restarts on the new mode's feature

        rul = None
        if det.alarm and h.fault_mode in PROGRESSIVE and h.fault_mode in model.measurement:
            spec = model.measurement[h.fault_mode]
            pf = ParticleFilterPrognoser(spec.config_for(position) or model.prognoser,
                                         spec.model_for(position))
            clock = _stress_clock(model, spec, h, base, index)
            state = None
            if h.prognosis is not None:
                try:
                    state = PrognoserState.from_dict(h.prognosis)
                    value = generic.get(spec.feature)
                    if value is not None and math.isfinite(value):
                        state = pf.update(state, value, index,
                                          stress=_stress(clock, state, index))
                    rul = _predict(pf, state, index, clock)
                except ValueError:
                    # the stored filter belongs to another model version (a new model was
                    # activated): start again from this actuator's history
                    state = None
            if state is None:
                since = h.alarm_index if h.alarm_index is not None else -1
                if spec.replay_from_onset:
                    since = min(since, _growth_onset(spec, position, h.history))
                state = _replay(model, h.fault_mode, position,
                                [(i, v) for i, v in h.history if i >= since], seed, clock)
                rul = None if state is None else _predict(pf, state, index, clock)
            if state is not None:
                h.prognosis = state.to_dict()

        feats = {name: features.summaries[name].to_dict()
                 for name in actuator_feature_names(position) if name in features.summaries}
        out[position] = ActuatorOutcome(
            flight_index=index, features=feats,
            z={n: v for n in actuator_feature_names(position)
               if (v := _finite(z_all.get(n, math.nan))) is not None},
            confidence=dict(det.confidence), max_confidence=float(det.max_confidence),
            alarm=det.alarm, new_alarm=det.new_alarm, alarm_features=list(det.alarm_features),
            class_probabilities=probs, fault_mode=h.fault_mode if det.alarm else None, rul=rul)
    return out
