"""The kernel in lanes: each lane's outputs (signals, surfaces, true states, accumulators) are
bit for bit those of the scalar kernel that ran one flight a call, on every fault mode, both
winglet modes, sensor injections, station conditions and open MOSFETs, with flights of
different lengths in one call, whatever the number of lanes and a flight's place among them;
and a batch of flights gives each flight's log and summary as it flies alone."""

from __future__ import annotations

import numpy as np
import pytest

from sim_worker.conditions import Conditions
from sim_worker.faults import THRESHOLDS, FaultState, healthy
from sim_worker.fleet import WingletMode, build_aircraft
from sim_worker.flight import (
    FlightSpec,
    run_kernel,
    run_kernels,
    simulate_flight,
    simulate_flights,
)
from sim_worker.kernel import MAX_LANES
from sim_worker.sensors import SensorInjection, degrade
from tests.sim.kernel_cases import CASES, SCALAR_DIGESTS, case_inputs, digest


@pytest.mark.parametrize("lanes", [1, 3, 8, MAX_LANES])
def test_every_lane_is_the_scalar_kernel_bit_for_bit(lanes: int) -> None:
    # 3 lanes run the loops' scalar remainder, 8 one pass of the 8-wide SIMD body, 16 two;
    # every call mixes flights of 1.5 to 3 s
    names = list(CASES)
    got = {}
    for start in range(0, len(names), lanes):
        batch = names[start:start + lanes]
        for name, res in zip(batch, run_kernels([case_inputs(n) for n in batch]), strict=True):
            got[name] = digest(res)
    assert got == SCALAR_DIGESTS


def test_a_flight_is_the_same_in_any_lane() -> None:
    # the same flight in the last lane of a full call, behind longer and shorter flights
    names = list(CASES)
    for name in ("SE", "standby BDO"):
        others = [case_inputs(n) for n in names if n != name][:MAX_LANES - 1]
        res = run_kernels([*others, case_inputs(name)])[-1]
        assert digest(res) == SCALAR_DIGESTS[name] == digest(run_kernel(case_inputs(name)))


def test_without_truth_the_other_outputs_are_unchanged() -> None:
    inputs = [case_inputs(n) for n in ("TTS", "standby healthy")]
    with_truth = run_kernels(inputs)
    without = run_kernels(inputs, truth=False)
    for a, b in zip(with_truth, without, strict=True):
        assert b.truth.shape[0] == 0
        for name in ("signals", "surfaces", "acc"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name))


def _specs() -> list[FlightSpec]:
    aircraft = build_aircraft("I-LANE02", "Turin", seed=7)
    thr = THRESHOLDS["TTS"]
    noisy = degrade(aircraft, [SensorInjection(1, "WT", "current", "noise", 3.0, 0)], 2)
    return [
        FlightSpec(aircraft, healthy(), 0, np.random.default_rng([1, 0]), duration_s=2.0),
        FlightSpec(aircraft, FaultState("TTS", "WL1", 0.5 * thr, thr), 1,
                   np.random.default_rng([1, 1]), duration_s=3.0,
                   winglet_mode=WingletMode.ACTIVE_STANDBY),
        FlightSpec(noisy, healthy(), 2, np.random.default_rng([1, 2]), duration_s=1.5,
                   conditions=Conditions(ambient_offset_k=10.0, load_scale=1.3)),
        FlightSpec(aircraft, FaultState("SE", "WT", 0.3, 0.5, phase_rad=0.5), 3,
                   np.random.default_rng([1, 3]), duration_s=2.5, flight_id="I-LANE02-SE"),
    ]


def test_flights_in_a_batch_are_the_flights_alone() -> None:
    batched = simulate_flights(_specs(), lanes=3)  # grouped by length: two kernel calls
    alone = [simulate_flight(s.aircraft, s.fault, s.flight_index, s.rng, flight_id=s.flight_id,
                             duration_s=s.duration_s, winglet_mode=s.winglet_mode,
                             conditions=s.conditions) for s in _specs()]
    assert len(batched) == len(alone) == 4
    for (log_b, sum_b), (log_a, sum_a) in zip(batched, alone, strict=True):
        assert log_b.metadata == log_a.metadata
        assert log_b.channels.keys() == log_a.channels.keys()
        for name, values in log_a.channels.items():
            np.testing.assert_array_equal(log_b.channels[name], values, err_msg=name)
        assert sum_b == sum_a
    assert [log.metadata.flight for log, _ in batched] == [
        "I-LANE02-F00000", "I-LANE02-F00001", "I-LANE02-F00002", "I-LANE02-SE"]


def test_a_batch_refuses_a_shared_generator_and_too_many_lanes() -> None:
    spec = _specs()[0]
    with pytest.raises(ValueError, match="own random generator"):
        simulate_flights([spec, spec])
    with pytest.raises(ValueError, match="lanes"):
        simulate_flights([spec], lanes=MAX_LANES + 1)
    with pytest.raises(ValueError, match="at most"):
        run_kernels([case_inputs("healthy")] * (MAX_LANES + 1))
