"""What the online judge carries from flight to flight for one unit (``ema-detection-state/2``,
JSON) and what it says about one flight."""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

__all__ = ["STATE_FORMAT", "DetectionResult", "DetectionState", "Observation"]

STATE_FORMAT = "ema-detection-state/2"
_STATE_FORMATS = (STATE_FORMAT, "ema-detection-state/1")  # /1 had no reference


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
    """Outcome of one flight's judgement of one unit."""

    confidence: dict[str, float]  # per feature, in [0, 1]
    max_confidence: float
    alarm: bool  # latched alarm state after this flight
    new_alarm: bool  # raised by this flight
    alarm_features: list[str]
    #: self-referenced residual of each feature with a valid value this flight
    z_self: dict[str, float] = field(default_factory=dict)
    #: the actuator's own offset ``u_hat`` (``z`` units) removed from each feature
    offset: dict[str, float] = field(default_factory=dict)
    #: features whose evidence was left to the partner drive this flight
    #: (:func:`~server.phm.detection.pair.partner_held`)
    held: list[str] = field(default_factory=list)
    #: while the unit is in alarm, the units the alarm may belong to and the probability of
    #: each on this flight (the ambiguity group,
    #: :func:`~server.phm.detection.pair.isolation_of`); empty otherwise
    isolation: dict[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class Observation:
    """One flight's judgement of one unit's features, before the alarm is decided."""

    confidence: dict[str, float]  # per feature, in [0, 1]
    #: per pair-coupled feature, how far the unit has moved
    #: (:func:`~server.phm.detection.pair.pair_level`)
    level: dict[str, float]
    z_self: dict[str, float]
    offset: dict[str, float]
