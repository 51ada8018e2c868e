"""False alarms per unit-flight: every alarm on an actuator without a fault, by cause."""

from __future__ import annotations

import pytest

from server.evaluation.false_alarms import against_design, exposure_of, summarise_false_alarms
from server.evaluation.report import _per_unit_flight
from server.phm.metrics import event_rate


def _trace(mode: str, position: str | None, onset: int | None, n: int,
           raised: dict[int, str], feature: str = "F_MTEL") -> dict:
    """A pattern's trace of ``n`` flights where ``raised`` maps flight -> unit newly alarmed
    on ``feature`` (alarms latch)."""
    flights, latched = [], set()
    for i in range(n):
        new = [raised[i]] if i in raised else []
        latched |= set(new)
        flights.append({"index": i, "new_alarms": new, "alarms": sorted(latched),
                        "raised_on": {u: [f"{u}.{feature}"] for u in new}})
    return {"id": f"{mode}-x", "mode": mode, "position": position, "onset": onset,
            "flights": flights}


def test_every_unit_without_a_fault_is_at_risk_until_it_alarms() -> None:
    mtel = _trace("MTEL", "WL1", 5, 10, {3: "WT", 6: "WL1", 7: "WL2"})
    exp = exposure_of(mtel)
    # before onset: 3 units x 5 flights, less WT after its alarm at flight 3 (flight 4)
    assert exp["unit_flights"]["before onset"] == 14
    # after onset: WL2, the partner, at risk on flights 5-7; WT already alarmed
    assert exp["unit_flights"]["partner drive"] == 3
    assert exp["unit_flights"]["other surface"] == 0
    assert [(e["unit"], e["cause"], e["age"]) for e in exp["events"]] == [
        ("WT", "before onset", 3), ("WL2", "partner drive", 7)]  # WL1 has the fault


def test_the_summary_sets_the_rate_beside_the_design_rate() -> None:
    healthy = _trace("healthy", None, None, 400, {320: "WT"}, feature="F_DMD")
    dmd = _trace("DMD", "WT", 2, 100, {})
    s = summarise_false_alarms([healthy, dmd], 3e-5)
    assert s["by_cause"]["healthy cycle"]["unit_flights"] == 400 * 3 - 79
    assert s["by_cause"]["other surface"]["unit_flights"] == 2 * 98
    assert s["events"] == 1 and s["unit_flights"] == 1121 + 3 * 2 + 196
    lo, hi = s["interval"]
    assert lo < s["rate"] < hi and s["rate"] == pytest.approx(1 / s["unit_flights"])
    # one alarm in 1,323 unit-flights: the rate's lower 90 % bound, 3.9e-5, is above 3e-5
    assert lo == pytest.approx(3.88e-5, rel=0.01) and s["design_rate_inside"] is False
    assert summarise_false_alarms([healthy, dmd], 1e-4)["design_rate_inside"] is True
    assert s["events_by_reference_age"] == {"0-49": 0, "50-149": 0, "150-299": 0, ">=300": 1}
    assert s["events_by_feature"] == {"F_DMD": 1} and s["list"][0]["features"] == ["WT.F_DMD"]
    none = summarise_false_alarms([dmd], 3e-5)
    assert none["events"] == 0 and none["interval"][0] == 0.0


def test_the_verification_rate_is_set_inside_or_outside_the_design_measured_interval() -> None:
    healthy = _trace("healthy", None, None, 400, {320: "WT"}, feature="F_DMD")
    s = summarise_false_alarms([healthy], 3e-5)  # 1 event on 1,121 unit-flights: 8.9e-4
    wide = {**event_rate(5, 10_676), "level": 0.9, "stated_rate": 3e-5}  # [1.8e-4, 9.8e-4]
    inside = against_design(s, wide)
    assert inside["within_design_interval"] is True
    measured = inside["design_measured"]
    assert measured["events"] == 5 and "stated_rate" not in measured
    quiet = against_design(s, {**event_rate(1, 100_000), "level": 0.9})
    assert quiet["within_design_interval"] is False
    assert against_design(s, None) == s  # a model without its design's record: nothing added
    text = "\n".join(_per_unit_flight({"per_unit_flight": inside}))
    assert "long healthy lives (leave-one-aircraft-out): 5 on 10676 unit-flights" in text
    assert "inside its interval" in text
