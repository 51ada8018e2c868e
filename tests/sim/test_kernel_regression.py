"""Bit-for-bit regression of the 12 kHz kernel: short flights hashed against recorded values.

The hashes are sha256 of the kernel's float64 outputs as computed at commit b52df62 (before the
kernel was split into subsystem functions). They must change only with a deliberate change of
the physics, the controller, the sensors or the random draws; a refactor must leave them alone.
After a deliberate change, re-record them with ``python tests/sim/test_kernel_regression.py``
and say why in the commit. (The hashes also depend on the platform's libm for cos, sin and exp:
a failure on a new kind of machine with no kernel change is that, not a physics change.)
"""

from __future__ import annotations

import hashlib

import numpy as np
import pytest

from sim_worker.faults import THRESHOLDS, FaultState, healthy
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
    "healthy": "4029094519e4a18f353c4629365a4eca5e4d9e0dd169a15e07335af137262e1d",
    "TTS": "6b7556bbfc22fdeaa1d0eb80ddd9f9370966554de8a9912dedd052bdf7d626a6",
    "DMD": "eabcf18930ea9c4c9c2316ccc69617a1052386faf5d818f5df4b5aea4b600752",
    "SE": "7fb52a0802a9b74f1d5dd11e8b79a5086cc7df0d488c5d067cc95e796aeacad7",
    "BDO": "4f349c13c7aaf8ad3023cdf4b67897c481f5d86440785f13322f1ddf736597af",
    "MTEL": "0b0ad0138fbd18b81e528ab8b590c230927af7e0a29e0f72d73b7d99e7c51fa4",
    "MTWEAR": "bfab169fc5f48662326acdc16266411e72e84abe6a8c3ef98dbcde75715b86a0",
    "REWEAR": "d949f40e5159ce93dcf987d234ff074fbb572e3bbfd39c3da0f822734d84a40a",
    "standby healthy": "8fe56e025c31e7875929fff635e7b3edd9420ca8a0c4b6d089188866484f3831",
    "standby TTS": "62ff24fe820f49464448084d510c2a2d5fd019496973a082abca0c23d58ade2e",
    "standby REWEAR": "f67d72245e798c8265033471190b83ba763ae756cfab5dea27f63c3cae43a8a4",
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
    if mode == "healthy":
        fault = healthy()
    else:
        thr = THRESHOLDS[mode]
        fault = FaultState(mode, position, severity_norm * thr, thr,
                           phase_rad=1.0 if mode == "SE" else 0.0)
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
