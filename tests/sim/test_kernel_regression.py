"""Bit-for-bit regression of the 12 kHz kernel: short flights hashed against recorded values.

The hashes are sha256 of the kernel's float64 outputs, compiled with the kernel's fastmath flags
(FMA contraction and reciprocals, see :mod:`sim_worker.kernel`). They must change only with a
deliberate change of the physics, the controller, the sensors, the random draws or the
compilation flags; a refactor must leave them alone. After a deliberate change, re-record them
with ``python tests/sim/test_kernel_regression.py`` and say why in the commit. (The hashes also
depend on the platform's libm for cos, sin and exp and, through FMA contraction, on whether the
CPU has fused multiply-add: a failure on a new kind of machine with no kernel change is that,
not a physics change.)
"""

from __future__ import annotations

import hashlib

import numpy as np
import pytest

from sim_worker.faults import fault_at
from sim_worker.fleet import WingletMode, active_channels, build_aircraft
from sim_worker.flight import draw_conditions, run_scenario
from sim_worker.kernel import simulate_motor
from sim_worker.params import MotorParams
from sim_worker.scenario import build_scenario

#: (mode, position, severity / threshold, winglet mode, flight): healthy, then every fault
#: mode on some position with both winglet drives active, then the winglet in active-standby
#: (flight 0: WL2 in standby; flight 1: WL1)
CASES: dict[str, tuple[str, str | None, float, WingletMode, int]] = {
    "healthy": ("healthy", None, 0.0, WingletMode.ACTIVE_ACTIVE, 0),
    "TTS": ("TTS", "WL1", 0.6, WingletMode.ACTIVE_ACTIVE, 0),
    "DMD": ("DMD", "WT", 0.6, WingletMode.ACTIVE_ACTIVE, 0),
    "SE": ("SE", "WL2", 0.6, WingletMode.ACTIVE_ACTIVE, 0),
    "BDO": ("BDO", "WT", 1.0, WingletMode.ACTIVE_ACTIVE, 0),
    "MTEL": ("MTEL", "WL1", 0.7, WingletMode.ACTIVE_ACTIVE, 0),
    "MTWEAR": ("MTWEAR", "WL2", 0.7, WingletMode.ACTIVE_ACTIVE, 0),
    "REWEAR": ("REWEAR", "WL1", 0.7, WingletMode.ACTIVE_ACTIVE, 0),
    "standby healthy": ("healthy", None, 0.0, WingletMode.ACTIVE_STANDBY, 0),
    "standby TTS": ("TTS", "WL2", 0.6, WingletMode.ACTIVE_STANDBY, 0),
    "standby REWEAR": ("REWEAR", "WL1", 0.7, WingletMode.ACTIVE_STANDBY, 1),
}

EXPECTED: dict[str, str] = {
    "healthy": "279e62b43d6a1bcf59c9d60a378a0c96f058e9ccbd957b7389b4b07a1b7e4d5f",
    "TTS": "a7f899512f77302b28a48010a693b933a56b83e4483eb884d75e15a419535fbc",
    "DMD": "52fd2a70c8482a6a2fdb0a72cd6070ffc5c82ae429efba4db438b2c71db6f5c6",
    "SE": "120eb6cd03cf054b679f86f5e2bc0e37440080d8d11305919050c0c051f221ca",
    "BDO": "34fb590a937c50ec888f4c6e4bd1ed60c3121f0e4fdd1a1d8962913a3d3294f4",
    "MTEL": "5118634d36f1f18376b1bb0a3ba361d8a465b45acbfec0628fb08f194b8275a5",
    "MTWEAR": "7fdaa7a14039630aed6a8a3b0b22f7a6394472615b3bf91fad5eb76caa3752ed",
    "REWEAR": "11cba0a96bdc8830971142f55cd60cc5f37a5fb4cfee292ca19494c77ea52dff",
    "standby healthy": "eabaeb942ecd7d37aedd33e0607763dbe20454d1200cd01aa5c65a96e4ed053d",
    "standby TTS": "17371622f0a97451207b4b8b8d7a8efef94734655a1e7c38d9330e28dc1f6b67",
    "standby REWEAR": "caa6c807e9b3915518f6427f6e1881a34183c7d91f0dea12b16e00dbc3268c8d",
}

EXPECTED_MOTOR = "c0b0407ad9ed9f2c4e29c02ceb1a52c5722a824db545550d387eeaba00179815"

_DURATION_S = 4.0  # the whole reference cycle compressed into a few seconds


def _sha(*arrays: np.ndarray) -> str:
    h = hashlib.sha256()
    for a in arrays:
        h.update(np.ascontiguousarray(a, dtype="<f8").tobytes())
    return h.hexdigest()


def flight_hash(case: str) -> str:
    mode, position, severity_norm, winglet_mode, flight = CASES[case]
    fault = fault_at(mode, position, severity_norm, phase_rad=1.0 if mode == "SE" else 0.0)
    aircraft = build_aircraft("I-HASH01", "Turin", seed=2024)
    rng = np.random.default_rng(7)
    cond = draw_conditions(aircraft, 0, rng)
    scenario = build_scenario(cond.warp, cond.ground_temp_c, rng, duration_s=_DURATION_S)
    res = run_scenario(aircraft, fault, scenario, rng,
                       active=active_channels(winglet_mode, flight))
    return _sha(res.signals, res.surfaces, res.truth, res.acc)


def motor_hash() -> str:
    m = MotorParams()
    u = np.zeros((6000, 2))
    u[:, 1] = 0.05 * 270.0
    u[3000:, 0] = -3.0
    out = np.zeros((6000, 3))
    simulate_motor(u, m.r_s_ohm, m.l_d_h, m.l_q_h, m.psi_pm_wb, float(m.pole_pairs), m.j_kgm2,
                   2e-4, 0.05, out)
    return _sha(out)


@pytest.mark.parametrize("case", list(CASES))
def test_flight_outputs_bit_for_bit(case: str) -> None:
    assert flight_hash(case) == EXPECTED[case]


def test_motor_bench_bit_for_bit() -> None:
    assert motor_hash() == EXPECTED_MOTOR


if __name__ == "__main__":  # print the values to record
    print("EXPECTED: dict[str, str] = {")
    for name in CASES:
        print(f'    "{name}": "{flight_hash(name)}",')
    print("}")
    print(f'EXPECTED_MOTOR = "{motor_hash()}"')
