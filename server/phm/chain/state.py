"""The state of one actuator carried between flights (``ema-actuator-health/3``, JSON)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from ..detection import DetectionState

__all__ = ["HEALTH_FORMAT", "ActuatorHealth"]

HEALTH_FORMAT = "ema-actuator-health/3"
#: earlier formats read: /1 (its history dropped, below), /2 (one filter, the leading mode's)
_READ_FORMATS = (HEALTH_FORMAT, "ema-actuator-health/2", "ema-actuator-health/1")


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
    #: sum of the (decayed) weights of the flights in ``class_log_prob``: the evidence is
    #: pooled as their weighted mean (chain.run._classify); None with no evidence yet
    class_weight: float | None = None
    fault_mode: str | None = None
    #: per mode, the decayed sum of its one-vs-rest decision values over the same flights as
    #: ``class_log_prob`` (pooled by ``class_weight``): each mode's own probability of being
    #: present (server.phm.classification.modes); None before the first classified flight
    mode_decision: dict[str, float] | None = None
    #: per mode, the decayed sum of its own feature in the classifier's input over the same
    #: flights (pooled by ``class_weight``): a mode beyond the leading mode's cross-talk is
    #: present too (server.phm.classification.crosstalk); None before the first classified
    #: flight
    own_feature: dict[str, float] | None = None
    #: the modes present on the last classified flight, the leading one first
    modes: list[str] = field(default_factory=list)
    #: per mode beside the leading one, its run of consecutive classified flights in the set;
    #: and the modes beside it confirmed present (classification.confirmation.advance_others)
    mode_runs: dict[str, int] = field(default_factory=dict)
    confirmed_modes: list[str] = field(default_factory=list)
    #: the confirmation rule's run (server.phm.classification.confirmation): how many
    #: classified flights in a row ``fault_mode`` has led, and the mode once confirmed
    class_run: int = 0
    confirmed_mode: str | None = None
    #: per progressive mode present, its particle filter's state (PrognoserState.to_dict)
    prognoses: dict[str, dict[str, Any]] = field(default_factory=dict)
    history: list[tuple[int, dict[str, float]]] = field(default_factory=list)
    #: take-off time (ISO 8601) of the last flight analysed and the aircraft's flying rate
    #: [flight/day], for the stress clock (server.phm.season)
    last_started_at: str | None = None
    flights_per_day: float | None = None

    @property
    def prognosis(self) -> dict[str, Any] | None:
        """The leading mode's filter state (None: none yet)."""
        return self.prognoses.get(self.fault_mode or "")

    @prognosis.setter
    def prognosis(self, state: dict[str, Any] | None) -> None:
        if self.fault_mode is None:
            raise ValueError("no leading mode to hold a filter for")
        if state is None:
            self.prognoses.pop(self.fault_mode, None)
        else:
            self.prognoses[self.fault_mode] = state

    def rearm(self) -> None:
        """After an inspection found no fault: clear the alarm latch, the class evidence and
        the filter, so a fault that (re)appears raises a new alarm and is classified afresh;
        the unit's own reference and residual history stay (it is the same unit)."""
        self.detection.alarm = False
        self.detection.alarm_flight = None
        self.detection.alarm_features = []
        self.alarm_index = None
        self.class_log_prob = None
        self.class_weight = None
        self.fault_mode = None
        self.mode_decision = None
        self.own_feature = None
        self.modes = []
        self.mode_runs = {}
        self.confirmed_modes = []
        self.class_run = 0
        self.confirmed_mode = None
        self.prognoses = {}

    def to_dict(self) -> dict[str, Any]:
        return {"format": HEALTH_FORMAT, "position": self.position,
                "detection": self.detection.to_dict(), "flights_seen": self.flights_seen,
                "alarm_index": self.alarm_index,
                "class_log_prob": self.class_log_prob, "class_weight": self.class_weight,
                "fault_mode": self.fault_mode, "mode_decision": self.mode_decision,
                "own_feature": self.own_feature, "modes": list(self.modes),
                "mode_runs": dict(self.mode_runs),
                "confirmed_modes": list(self.confirmed_modes), "class_run": self.class_run,
                "confirmed_mode": self.confirmed_mode,
                "prognoses": self.prognoses,
                "history": [[i, z] for i, z in self.history],
                "last_started_at": self.last_started_at,
                "flights_per_day": self.flights_per_day}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> ActuatorHealth:
        if d.get("format") not in _READ_FORMATS:
            raise ValueError(f"not a {HEALTH_FORMAT} document")
        prognoses = dict(d.get("prognoses") or {})
        if d.get("prognosis") is not None and d.get("fault_mode"):  # /1 and /2: the leader's
            prognoses[str(d["fault_mode"])] = d["prognosis"]
        # version 1 kept standardised residuals in the history; they cannot seed a filter that
        # tracks physical residuals, so that history is dropped (detection state is kept)
        keep_history = d.get("format") != "ema-actuator-health/1"
        return cls(position=str(d["position"]),
                   detection=DetectionState.from_dict(d["detection"]),
                   flights_seen=int(d["flights_seen"]),
                   alarm_index=None if d.get("alarm_index") is None else int(d["alarm_index"]),
                   class_log_prob=d.get("class_log_prob"), class_weight=d.get("class_weight"),
                   fault_mode=d.get("fault_mode"), mode_decision=d.get("mode_decision"),
                   own_feature=d.get("own_feature"), modes=[str(m) for m in d.get("modes") or []],
                   mode_runs={str(m): int(n) for m, n in (d.get("mode_runs") or {}).items()},
                   confirmed_modes=[str(m) for m in d.get("confirmed_modes") or []],
                   class_run=int(d.get("class_run") or 0),
                   confirmed_mode=d.get("confirmed_mode"),
                   prognoses=prognoses,
                   history=[(int(i), {k: float(v) for k, v in z.items()})
                            for i, z in d.get("history", [])] if keep_history else [],
                   last_started_at=d.get("last_started_at"),
                   flights_per_day=None if d.get("flights_per_day") is None
                   else float(d["flights_per_day"]))
