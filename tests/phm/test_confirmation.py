"""An alarm's class: provisional at the first alarm, confirmed when the evidence has said the
same for long enough."""

from __future__ import annotations

import pytest

from server.evaluation.scoring import UNCONFIRMED, UNDETECTED, confirmation_of
from server.phm.classification.confirmation import ConfirmationRule, first_confirmation

RULE = ConfirmationRule(flights=2, probability=0.9)
MTEL = {"MTEL": 0.93, "DMD": 0.07}
DMD = {"MTEL": 0.2, "DMD": 0.8}
SURE_DMD = {"MTEL": 0.04, "DMD": 0.96}


def test_the_leading_mode_confirms_on_its_second_flight_in_a_row_at_the_probability() -> None:
    assert first_confirmation(RULE, [MTEL, MTEL]) == (1, "MTEL")
    # a change of leader restarts the run; a flight below the probability does not confirm
    assert first_confirmation(RULE, [MTEL, DMD, SURE_DMD]) == (2, "DMD")
    assert first_confirmation(RULE, [DMD, DMD, DMD]) is None
    # an unclassified flight breaks the run
    assert first_confirmation(RULE, [MTEL, None, MTEL, MTEL]) == (3, "MTEL")
    assert first_confirmation(ConfirmationRule(flights=1, probability=0.9), [MTEL]) == \
        (0, "MTEL")


def test_a_rule_without_a_flight_or_outside_a_probability_is_refused() -> None:
    with pytest.raises(ValueError):
        ConfirmationRule(flights=0)
    with pytest.raises(ValueError):
        ConfirmationRule(probability=1.5)


def test_the_evaluation_reads_the_confirmation_from_the_alarm_on() -> None:
    flights = [{"index": i, "probs": p} for i, p in enumerate(
        [None, None, DMD, MTEL, MTEL, MTEL])]
    trace = {"mode": "MTEL", "flights": flights}
    assert confirmation_of(trace, 2, RULE) == ("MTEL", 2)  # flight 4, two after the alarm
    assert confirmation_of(trace, None, RULE) == (UNDETECTED, None)
    assert confirmation_of({"mode": "MTEL", "flights": flights[:4]}, 2, RULE) == \
        (UNCONFIRMED, None)


def test_the_chain_confirms_once_per_alarm_and_keeps_its_run_across_a_restart() -> None:
    from server.phm.chain.run import _confirm
    from server.phm.chain.state import ActuatorHealth
    from server.phm.detection import DetectionState

    h = ActuatorHealth(position="WT", detection=DetectionState.new("WT", ["WT.F_MTEL"]))
    assert _confirm(h, None, MTEL) is None and h.class_run == 1
    h = ActuatorHealth.from_dict(h.to_dict())  # the service stores the state between flights
    assert _confirm(h, "DMD", MTEL) is None and h.class_run == 1  # a new leader: run again
    assert _confirm(h, "MTEL", MTEL) == "MTEL" and h.confirmed_mode == "MTEL"
    assert _confirm(h, "MTEL", MTEL) is None  # once
    h.rearm()  # no fault found: a new alarm is confirmed afresh
    assert (h.fault_mode, h.class_run, h.confirmed_mode) == (None, 0, None)


def test_the_summary_counts_a_pattern_that_ended_before_the_rule_could_hold() -> None:
    from server.evaluation.scoring import classification_summary

    def trace(i: int, probs: list) -> dict:
        return {"id": f"SE-{i}", "mode": "SE", "position": "WT", "onset": 0, "failure": None,
                "flights": [{"index": k, "alarm": p is not None, "new_alarms": [],
                             "probs": p} for k, p in enumerate(probs)]}

    se = {"SE": 0.97, "MTEL": 0.03}
    s = classification_summary([trace(0, [None, se, se]), trace(1, [None, None, se])],
                               ["MTEL", "SE"])
    assert s["flights_to_confirmation"]["confirmed"] == 1
    assert s["flights_to_confirmation"]["ended_before_due"] == 1
    assert s["at_confirmation"]["matrix"][s["at_confirmation"]["rows"].index("SE")] == \
        [0, 1, 1, 0]  # MTEL, SE, unconfirmed, undetected
