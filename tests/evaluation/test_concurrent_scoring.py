"""Scoring a concurrent pattern (server.evaluation.concurrent_scoring) on traces written by
hand: when each fault counts as alarmed and named, the first fault's half life, a second fault
started after it, spurious modes, and the earlier failure scored on its own unit."""

from __future__ import annotations

from typing import Any

from server.evaluation.concurrent_scoring import score_concurrent, score_pattern


def _fault(mode: str, position: str, onset: int, *, failure: int | None, end: int,
           span: float = 40.0) -> dict[str, Any]:
    return {"mode": mode, "position": position, "onset_flight": onset, "span_flights": span,
            "started": True, "outcome": "failed" if failure is not None else "censored",
            "end_flight": end, "failure_flight": failure}


def _unit(modes: list[str], rul: float | None = None, new: bool = False) -> dict[str, Any]:
    doc = None if rul is None else {"quantiles": [[0.05, 0.8 * rul], [0.25, 0.9 * rul],
                                                  [0.5, rul], [0.75, 1.1 * rul],
                                                  [0.95, 1.2 * rul]]}
    return {"new_alarm": new, "probs": {modes[0]: 0.9}, "fault_mode": modes[0],
            "modes": modes, "rul": doc}


def _trace(faults: list[dict[str, Any]], units_of: Any, last: int) -> dict[str, Any]:
    flights = [{"index": i, "units": units_of(i)} for i in range(last + 1)]
    truth = [{"index": i, "faults": [{"mode": f["mode"], "position": f["position"]}
                                     for f in faults if f["onset_flight"] <= i <= f["end_flight"]]}
             for i in range(last + 1)]
    return {"id": "C-1", "aircraft": "I-CON-01", "combination": "TTS+DMD", "horizon": 500.0,
            "flights": flights, "truth": {"faults": faults, "flights": truth}}


def test_two_modes_of_one_unit_named_by_the_first_half_life() -> None:
    """TTS from flight 10 fails at 50 (half life at 30); DMD from 20, censored at 50. The unit
    alarms at 14 (TTS), names DMD from 28: both named at the half flight. Its RUL, exact from
    the alarm on, scores the TTS failure with RA 1 and a horizon from the alarm on."""
    faults = [_fault("TTS", "WL1", 10, failure=50, end=50),
              _fault("DMD", "WL1", 20, failure=None, end=50)]

    def units(i: int) -> dict[str, Any]:
        if i < 14:
            return {}
        return {"WL1": _unit(["TTS", "DMD"] if i >= 28 else ["TTS"], rul=50.0 - i,
                             new=i == 14)}

    row = score_pattern(_trace(faults, units, 50))
    tts, dmd = row["faults"]
    assert (tts["alarmed"], tts["named"], dmd["alarmed"], dmd["named"]) == (14, 14, 20, 28)
    assert row["half_flight"] == 30.0 and row["eligible_at_half"]
    assert row["named_at_half"] is True and row["named_by_half"] is True
    assert row["named_ever"] is True
    early = row["earlier_failure"]
    assert (early["mode"], early["position"], early["detected_index"]) == ("TTS", "WL1", 14)
    assert early["ra"] > 0.99 and early["ph"] == 0.9  # (50 - 14) / 40: from the alarm on
    assert row["spurious_unit_flights"] == 0


def test_a_second_mode_named_late_or_on_the_wrong_unit() -> None:
    """The second mode named only after the half flight misses it; a mode named beside the
    leading one on a unit that does not carry it is spurious; a second fault starting after
    the half flight makes the pattern ineligible, not a miss."""
    faults = [_fault("TTS", "WL1", 10, failure=50, end=50),
              _fault("DMD", "WL1", 20, failure=None, end=50)]

    def late(i: int) -> dict[str, Any]:
        if i < 14:
            return {}
        units = {"WL1": _unit(["TTS", "DMD"] if i >= 40 else ["TTS"], rul=50.0 - i)}
        if i >= 45:
            units["WT"] = _unit(["MTEL", "DMD"])
        return units

    row = score_pattern(_trace(faults, late, 50))
    assert row["faults"][1]["named"] == 40 and row["named_at_half"] is False
    assert row["named_by_half"] is False
    assert row["named_ever"] is True
    # DMD named beside MTEL on WT, which carries no DMD (WL1 does): spurious on 45-50 (the
    # leading mode on a unit without a fault is an alarm, counted as isolation, not here)
    assert row["spurious_unit_flights"] == 6
    faults_late = [_fault("TTS", "WL1", 10, failure=50, end=50),
                   _fault("DMD", "WT", 35, failure=None, end=50)]
    row = score_pattern(_trace(faults_late, late, 50))
    assert row["eligible_at_half"] is False and row["named_at_half"] is None
    assert row["named_by_half"] is None
    # WT now carries the DMD it names; WL1 names a DMD it no longer carries, 40-50
    assert row["spurious_unit_flights"] == 11
    summary = score_concurrent([_trace(faults, late, 50), _trace(faults_late, late, 50)])
    assert summary["all"]["named_at_half"]["n"] == 1
    assert summary["all"]["second_after_half"] == 1
    assert summary["combinations"]["TTS+DMD"]["faults_alarmed"]["hits"] == 4


def test_a_mode_named_before_the_half_flight_and_dropped_on_it() -> None:
    """Named by the half flight, not still named on it: the provisional set dropped it."""
    faults = [_fault("TTS", "WL1", 10, failure=50, end=50),
              _fault("DMD", "WL1", 20, failure=None, end=50)]

    def flicker(i: int) -> dict[str, Any]:
        if i < 14:
            return {}
        return {"WL1": _unit(["TTS", "DMD"] if 24 <= i < 30 else ["TTS"], rul=50.0 - i)}

    row = score_pattern(_trace(faults, flicker, 50))
    assert row["faults"][1]["named"] == 24
    assert (row["named_by_half"], row["named_at_half"]) == (True, False)


def test_a_confirmation_of_a_mode_the_unit_does_not_carry_is_spurious() -> None:
    """WL1 carries TTS from 10 and confirms it at 15 (its class) and DMD beside it at 30: DMD
    starts on WT, not WL1, so that confirmation is spurious: 1 of 2."""
    faults = [_fault("TTS", "WL1", 10, failure=50, end=50),
              _fault("DMD", "WT", 20, failure=None, end=50)]

    def units(i: int) -> dict[str, Any]:
        if i < 14:
            return {}
        unit = _unit(["TTS", "DMD"] if i >= 29 else ["TTS"], rul=50.0 - i)
        unit["confirmed"] = "TTS" if i == 15 else None
        unit["confirmed_others"] = ["DMD"] if i == 30 else []
        return {"WL1": unit}

    row = score_pattern(_trace(faults, units, 50))
    assert (row["spurious_confirmations"], row["confirmations"]) == (1, 2)
    assert row["faults"][0]["confirmed"] == 15 and row["faults"][1]["confirmed"] is None
    summary = score_concurrent([_trace(faults, units, 50)])["all"]
    assert (summary["spurious_confirmations"]["hits"],
            summary["spurious_confirmations"]["n"]) == (1, 2)
