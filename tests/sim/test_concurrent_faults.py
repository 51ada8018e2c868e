"""Concurrent faults: both faults' entries in the kernel's parameter rows, the same mode twice
on a position refused, each fault progressing by itself, and the failure semantics of a
concurrent pattern (the failed actuator replaced, every fault on it ended, a second one
censored, a fault on another actuator flying on)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from server.flightlog import read_parquet
from server.vocabulary import POSITIONS
from sim_worker.campaign import SCALES, ParquetSink, PatternTask, plan_campaign
from sim_worker.campaign.pattern import pattern_flights
from sim_worker.campaign.planning import COMBINATIONS, PLACES, flight_rng
from sim_worker.faults import (
    PROGRESSIVE,
    THRESHOLDS,
    FaultState,
    advance_fault,
    as_faults,
    fault_at,
    healthy,
    merged_entries,
    new_fault,
)
from sim_worker.fleet import Aircraft
from sim_worker.flight import kernel_inputs, reference_summary, simulate_flights
from tests.sim.helpers import const, make_scenario

CFG = SCALES["ci"]["concurrent"]
OPTIONS = {"bases": None, "noise_scale": 1.0, "sensor_faults": ()}


def _rows(aircraft: Aircraft, fault: Any) -> np.ndarray:
    scenario = make_scenario(0.05, const(0.0), const(0.0), const(0.0), const(0.0))
    return kernel_inputs(aircraft, fault, scenario, np.random.default_rng(0)).params


@pytest.mark.parametrize("modes", [("MTWEAR", "MTEL"), ("TTS", "DMD"), ("REWEAR", "MTWEAR"),
                                   ("SE", "BDO")])
def test_two_faults_on_one_actuator_set_both_entries_as_each_alone(
        aircraft: Aircraft, modes: tuple[str, str]) -> None:
    a, b = (fault_at(m, "WL2", 0.6, phase_rad=0.4) for m in modes)
    base, only_a, only_b, both = (_rows(aircraft, f) for f in (healthy(), a, b, (a, b)))
    moved_a, moved_b = only_a != base, only_b != base
    assert moved_a.any() and moved_b.any()
    assert not (moved_a & moved_b).any(), "two modes wrote one parameter entry"
    np.testing.assert_array_equal(both[moved_a], only_a[moved_a])
    np.testing.assert_array_equal(both[moved_b], only_b[moved_b])
    np.testing.assert_array_equal(both[~(moved_a | moved_b)], base[~(moved_a | moved_b)])
    assert not moved_a[[POSITIONS.index(p) for p in POSITIONS if p != "WL2"]].any()


def test_faults_on_two_actuators_each_set_their_own_row(aircraft: Aircraft) -> None:
    wt, wl = fault_at("DMD", "WT", 0.5), fault_at("MTEL", "WL1", 0.5)
    both = _rows(aircraft, (wt, wl))
    np.testing.assert_array_equal(both[POSITIONS.index("WT")],
                                  _rows(aircraft, wt)[POSITIONS.index("WT")])
    np.testing.assert_array_equal(both[POSITIONS.index("WL1")],
                                  _rows(aircraft, wl)[POSITIONS.index("WL1")])
    assert merged_entries((wt, wl), "WL2") == {}


def test_one_fault_as_a_tuple_packs_as_the_fault(aircraft: Aircraft) -> None:
    fault = fault_at("TTS", "WT", 0.7)
    np.testing.assert_array_equal(_rows(aircraft, (fault,)), _rows(aircraft, fault))
    np.testing.assert_array_equal(_rows(aircraft, ()), _rows(aircraft, healthy()))


def test_the_same_mode_twice_on_one_actuator_is_refused(aircraft: Aircraft) -> None:
    twice = (fault_at("MTWEAR", "WL1", 0.2), fault_at("MTWEAR", "WL1", 0.4))
    with pytest.raises(ValueError, match="two MTWEAR faults on WL1"):
        _rows(aircraft, twice)
    # the same mode on two actuators is two faults
    _rows(aircraft, (fault_at("MTWEAR", "WL1", 0.2), fault_at("MTWEAR", "WT", 0.4)))


@pytest.mark.parametrize("bad, message", [
    (FaultState("TTS", "WL3", 0.01, 0.1), "position among"),
    (FaultState("TTS", None, 0.01, 0.1), "position among"),
    (FaultState("WEAR", "WT", 0.01, 0.1), "unknown fault mode"),
])
def test_a_fault_off_the_half_wing_is_refused(bad: FaultState, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        as_faults((fault_at("DMD", "WT", 0.3), bad))


def test_every_combination_is_two_progressive_modes_where_campaigns_place_them() -> None:
    specs = plan_campaign("concurrent", 3, "quick")
    assert [s.mode for s in specs] == [c.name for c in COMBINATIONS for _ in range(3)]
    for s in specs:
        first, second = s.faults
        assert {first.mode, second.mode} <= set(PROGRESSIVE)
        assert all(f.position in PLACES[f.mode] for f in s.faults)
        assert (first.mode, first.position) != (second.mode, second.position)
        quick = SCALES["quick"]["concurrent"]
        assert second.onset > first.onset == quick.lead_flights == s.onset
        lo, hi = quick.span_flights  # each span drawn by the scale's law
        assert all(lo <= f.span_flights <= hi for f in s.faults)
    same = {c.name for c in COMBINATIONS if c.modes is not None}
    for s in specs:
        positions = {f.position for f in s.faults}
        assert len(positions) == (1 if s.mode in same else 2)
    assert {s.faults[0].mode for s in specs if s.mode == "MTWEAR+MTEL"} == {"MTWEAR", "MTEL"}


def test_concurrent_seeds_and_tails_are_their_own() -> None:
    from sim_worker.campaign import fleet_for

    conc = plan_campaign("concurrent", 0, "ci")
    others = plan_campaign("design", 0, "ci") + plan_campaign("verification", 0, "ci")
    assert not {s.seed for s in conc} & {s.seed for s in others}
    tails = {a.tail for a in fleet_for("concurrent", 0)}
    assert all(t.startswith("I-CON") for t in tails)
    assert not {a.seed for a in fleet_for("concurrent", 0)} & {
        a.seed for k in ("design", "verification") for a in fleet_for(k, 0)}
    assert [s.id for s in plan_campaign("concurrent", 0, "ci", per_mode=1)] == [
        s.id for s in conc if s.id.endswith("-01")]


def test_a_scale_without_concurrent_patterns_is_refused() -> None:
    with pytest.raises(ValueError, match="the paper scale has no concurrent campaign"):
        plan_campaign("concurrent", 0, "paper")


def _fly(spec_number: int, out: Path) -> tuple[dict[str, Any], dict[int, Any], dict[int, Any]]:
    """One ci concurrent pattern run flight by flight: its result, and each flight's
    summary and log metadata by index."""
    spec = plan_campaign("concurrent", 0, "ci")[spec_number]
    run = pattern_flights(PatternTask(out, "concurrent", 0, CFG, spec, OPTIONS, ParquetSink()))
    summaries: dict[int, Any] = {}
    metadata: dict[int, Any] = {}
    flight = next(run)
    while True:
        log, summary = simulate_flights([flight])[0]
        summaries[flight.flight_index], metadata[flight.flight_index] = summary, log.metadata
        try:
            flight = run.send((log, summary))
        except StopIteration as done:
            return done.value, summaries, metadata


@pytest.fixture(scope="module")
def flown(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """Two ci patterns: two faults on one winglet drive, and the wingtip with a winglet drive."""
    out = tmp_path_factory.mktemp("concurrent")
    specs = plan_campaign("concurrent", 0, "ci")
    numbers = [next(i for i, s in enumerate(specs) if s.mode == m)
               for m in ("MTWEAR+MTEL", "WT+WL")]
    return {specs[i].mode: (specs[i], *_fly(i, out), out) for i in numbers}


def _path(entry: dict[str, Any], mode: str, position: str) -> dict[int, float]:
    return {fl["index"]: f["severity"] for fl in entry["flights"] for f in fl["faults"]
            if (f["mode"], f["position"]) == (mode, position)}


@pytest.mark.parametrize("combination", ["MTWEAR+MTEL", "WT+WL"])
def test_each_fault_progresses_as_it_would_alone_on_the_same_flights(
        flown: dict[str, Any], combination: str) -> None:
    """Each fault's severity path is its lone progression (its own onset, rate and random
    stream) over the summaries the pattern flew."""
    spec, result, summaries, _, _ = flown[combination]
    entry = result["entry"]
    from sim_worker.campaign import fleet_for

    aircraft = fleet_for("concurrent", 0)[spec.aircraft_index]
    for k, plan in enumerate(spec.faults):
        ref = reference_summary(aircraft, plan.position, duration_s=CFG.duration_s,
                                seed=spec.seed)
        state = new_fault(plan.mode, plan.position, np.random.default_rng([spec.seed, 7, k]),
                          reference=ref, span_flights=plan.span_flights)
        path = _path(entry, plan.mode, plan.position)
        assert min(path) == plan.onset and len(path) >= 2
        for index in sorted(path):
            assert path[index] == state.severity, (plan, index)
            state = advance_fault(state, summaries[index], flight_rng(spec, index, 10 + k))


def test_a_failed_actuator_ends_every_fault_on_it(flown: dict[str, Any]) -> None:
    """Two faults on one actuator: the first at its threshold fails the actuator on that
    flight (rendered, true RUL 0), the other is censored there (no RUL, no failure flight),
    and the pattern ends."""
    spec, result, _, _, _ = flown["MTWEAR+MTEL"]
    entry = result["entry"]
    faults = {f["mode"]: f for f in entry["faults"]}
    failed = [f for f in faults.values() if f["outcome"] == "failed"]
    assert len(failed) == 1, faults
    end = failed[0]["failure_flight"]
    assert failed[0]["end_flight"] == end and failed[0]["severity_norm_at_end"] >= 1.0
    other = next(f for f in faults.values() if f is not failed[0])
    assert other["outcome"] == "censored" and other["end_flight"] == end
    assert other["failure_flight"] is None and other["severity_norm_at_end"] < 1.0
    assert entry["flights"][-1]["index"] == end
    for fl in entry["flights"]:
        for f in fl["faults"]:
            if f["mode"] == failed[0]["mode"]:
                assert f["true_rul_flights"] == end - fl["index"] and f["failure_flight"] == end
            else:
                assert f["true_rul_flights"] is None and f["failure_flight"] is None
    assert [f["mode"] for f in entry["flights"][-1]["faults"]] == [
        p.mode for p in spec.faults]  # the failure flight flies both
    assert {"severity", "severity_norm", "true_rul_flights"}.isdisjoint(entry["flights"][0])
    assert entry["flights"][0]["faults"] == []  # the healthy lead


def test_a_fault_on_another_actuator_flies_on_after_a_replacement(
        flown: dict[str, Any]) -> None:
    """The wingtip with a winglet drive: each fault runs to its own threshold; after the
    first failure its actuator flies healthy under a new serial while the other progresses."""
    spec, result, _, metadata, out = flown["WT+WL"]
    entry = result["entry"]
    assert all(f["outcome"] == "failed" for f in entry["faults"])
    first, last = sorted(entry["faults"], key=lambda f: f["failure_flight"])
    assert first["failure_flight"] < last["failure_flight"] == entry["flights"][-1]["index"]
    original = metadata[0].actuator_serials
    for fl in entry["flights"]:
        on = {f["position"] for f in fl["faults"]}
        serials = metadata[fl["index"]].actuator_serials
        if fl["index"] > first["failure_flight"]:
            assert first["position"] not in on and last["position"] in on
            assert serials[first["position"]] == original[first["position"]] + "-R1"
        else:
            assert serials == original
        assert read_parquet((out / fl["file"]).read_bytes()).metadata.actuator_serials == \
            serials
    assert THRESHOLDS[first["mode"]] == first["threshold"]
