"""Isolation accuracy: every alarm after onset names its unit, ambiguity groups included."""

from __future__ import annotations

import pytest

from server.evaluation.isolation import isolation_cases, summarise_isolation


def _trace(mode: str, position: str | None, onset: int, raised: dict[int, dict]) -> dict:
    """``raised``: flight -> {unit: its group (None: an alarm recorded without one)}."""
    flights = []
    for i in range(12):
        new = raised.get(i, {})
        flights.append({"index": i, "new_alarms": sorted(new),
                        "isolation": {u: g for u, g in new.items() if g is not None}})
    return {"id": f"{mode}-{position}", "mode": mode, "position": position, "onset": onset,
            "flights": flights}


def test_the_named_unit_is_the_most_probable_of_the_group() -> None:
    mtel = _trace("MTEL", "WL2", 2, {
        1: {"WT": {"WT": 1.0}},  # before onset: a false alarm, not an isolation case
        4: {"WL1": {"WL1": 0.7, "WL2": 0.3}},  # the partner, named wrongly, the right one in
        6: {"WL2": {"WL2": 0.9, "WL1": 0.1}, "WT": None}})  # no group recorded: its own unit
    cases = isolation_cases(mtel)
    assert [(c["unit"], c["named"], c["right"], c["in_group"]) for c in cases] == [
        ("WL1", "WL1", False, True), ("WL2", "WL2", True, True), ("WT", "WT", False, False)]
    assert isolation_cases(_trace("healthy", None, 0, {3: {"WT": None}})) == []


def test_the_summary_counts_shares_with_their_intervals() -> None:
    traces = [_trace("MTEL", "WL2", 2, {6: {"WL2": {"WL2": 0.9, "WL1": 0.1}}}),
              _trace("DMD", "WT", 0, {3: {"WT": {"WT": 1.0}}}),
              _trace("TTS", "WL1", 0, {5: {"WT": {"WT": 1.0}}, 7: {"WL1": None}})]
    s = summarise_isolation(traces)
    assert s["named_right"]["hits"] == 3 and s["named_right"]["alarms"] == 4
    lo, hi = s["named_right"]["interval"]
    assert lo < 0.75 < hi and s["named_right"]["share"] == pytest.approx(0.75)
    assert s["ambiguity_groups"] == 1 and s["groups_named_right"] == 1
    assert s["groups_mean_named_probability"] == pytest.approx(0.9)
    assert [w["unit"] for w in s["wrong"]] == ["WT"]
