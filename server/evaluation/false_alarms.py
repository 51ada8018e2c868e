"""False alarms per unit and flight: every alarm on an actuator that has no fault.

An actuator without a fault is at risk on every flight until it alarms (the alarm latches
for the rest of the pattern, as in service until maintenance): on a healthy cycle, before a
fault's onset, and, after onset, on the faulty drive's partner (the other drive of the winglet
tab) and on the other surface. Each alarm there is a false-alarm event, whatever its aircraft
carries elsewhere. The rate is events per unit-flight at risk, with its exact (Clopper-Pearson)
90 % interval, set beside the detector's design rate; the events are split by cause and by the
age of the unit's reference (flights since the unit was installed: its reference is its first
valid flights) and by the features they were raised on.

Two design rates stand beside it: the one the bands are set for (stated, ``design_rate``), and
the one the design measured over its own long healthy lives with its interval (the training
report's ``design_false_alarms``, :func:`~server.phm.detection_model.healthy_alarm_rate`); the
verification's rate should fall inside the measured one's interval (:func:`against_design`).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping, Sequence
from typing import Any

from server.phm.detection import generic_feature
from server.phm.metrics import event_rate
from server.vocabulary import POSITIONS, alarming_positions, is_winglet

__all__ = ["CAUSES", "AGE_BINS", "against_design", "exposure_of", "summarise_false_alarms"]

#: where a unit without a fault flies
CAUSES: tuple[str, ...] = ("healthy cycle", "before onset", "partner drive", "other surface")
#: reference ages [flights since installation], lower bounds of the bins
AGE_BINS: tuple[int, ...] = (0, 50, 150, 300)
LEVEL = 0.90


def _causes_after_onset(trace: Mapping[str, Any]) -> dict[str, str | None]:
    """Why each unit has no fault once the pattern's fault is on (None: it has the fault)."""
    faulty = (set() if trace["mode"] == "healthy" else
              alarming_positions(trace["mode"], trace["position"],
                                 pair_rod_ends=bool(trace.get("pair_rod_ends", False))))
    return {u: None if u in faulty else
            "partner drive" if any(is_winglet(u) == is_winglet(p) for p in faulty)
            else "other surface" for u in POSITIONS}


def _cause(trace: Mapping[str, Any], after_onset: Mapping[str, str | None], unit: str,
           index: int) -> str | None:
    """Why ``unit`` has no fault on flight ``index`` of the pattern (None: it has one)."""
    if trace["mode"] == "healthy":
        return "healthy cycle"
    if index < int(trace["onset"] or 0):
        return "before onset"
    return after_onset[unit]


def _age_bin(age: int) -> str:
    lows = [b for b in AGE_BINS if b <= age]
    i = AGE_BINS.index(lows[-1])
    return (f"{AGE_BINS[i]}-{AGE_BINS[i + 1] - 1}" if i + 1 < len(AGE_BINS)
            else f">={AGE_BINS[i]}")


def exposure_of(trace: Mapping[str, Any]) -> dict[str, Any]:
    """Unit-flights at risk and false-alarm events of one pattern's trace, by cause."""
    flights = trace["flights"]
    first = int(flights[0]["index"]) if flights else 0
    at_risk = dict.fromkeys(CAUSES, 0)
    events: list[dict[str, Any]] = []
    alarmed: set[str] = set()
    after_onset = _causes_after_onset(trace)
    for f in flights:
        index = int(f["index"])
        new = set(f["new_alarms"])
        for unit in POSITIONS:
            if unit in alarmed:
                continue
            cause = _cause(trace, after_onset, unit, index)
            if cause is None:
                continue
            at_risk[cause] += 1
            if unit in new:
                events.append({"pattern": trace["id"], "unit": unit, "flight": index,
                               "cause": cause, "age": index - first,
                               "features": list(f.get("raised_on", {}).get(unit, []))})
        alarmed |= set(f["alarms"])
    return {"unit_flights": at_risk, "events": events}


def summarise_false_alarms(traces: Sequence[Mapping[str, Any]],
                           design_rate: float | None) -> dict[str, Any]:
    """Events per unit-flight over every unit without a fault, with the interval, the design
    rate beside it, and the split by cause and by reference age."""
    per = [exposure_of(t) for t in traces]
    events = [e for p in per for e in p["events"]]
    by_cause = {c: event_rate(sum(e["cause"] == c for e in events),
                              sum(p["unit_flights"][c] for p in per), LEVEL) for c in CAUSES}
    total = event_rate(len(events), sum(r["unit_flights"] for r in by_cause.values()), LEVEL)
    ages = {b: sum(_age_bin(e["age"]) == b for e in events)
            for b in dict.fromkeys(_age_bin(a) for a in AGE_BINS)}
    features = Counter(generic_feature(n) for e in events for n in e["features"])
    return {**total, "level": LEVEL, "design_rate": design_rate,
            "design_rate_inside": (None if total["interval"] is None or design_rate is None
                                   else total["interval"][0] <= design_rate
                                   <= total["interval"][1]),
            "by_cause": by_cause, "events_by_reference_age": ages,
            "events_by_feature": dict(sorted(features.items())), "list": events}


def against_design(per_unit_flight: Mapping[str, Any], measured: Mapping[str, Any] | None
                   ) -> dict[str, Any]:
    """``per_unit_flight`` (:func:`summarise_false_alarms`) with the design's measured rate
    beside it (``design_measured``: events, unit-flights, rate, interval) and whether the
    verification's rate falls inside that interval (``within_design_interval``; None without
    a measured design rate or a verification rate)."""
    out = dict(per_unit_flight)
    if not measured or measured.get("interval") is None:
        return out
    keep = ("events", "unit_flights", "rate", "interval", "level")
    out["design_measured"] = {k: measured[k] for k in keep if k in measured}
    rate = per_unit_flight.get("rate")
    lo, hi = measured["interval"]
    out["within_design_interval"] = None if rate is None else bool(lo <= rate <= hi)
    return out
