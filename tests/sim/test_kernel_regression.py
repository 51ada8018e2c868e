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
    "healthy": "26df7d4dc55189b7b96361fa9010ef6cd121ac9ea6c6cbdbf619e1143f3f94c4",
    "TTS": "8b6c58ced461f6ed765b54450a1a554b0d27a3ef41d8d9aed49efae843d46342",
    "DMD": "dff70c2d57ca9b608b8231e481406a10a2b3811dd13735bc56f3e9d69c3f9882",
    "SE": "8d025ba98925274bd60cf6579aa9b05ba3102d0c6747e61533e9149fbd2a2475",
    "BDO": "04be4173c4630d444e77f32b264d450e546c444505397447eba582c6ddb1395d",
    "MTEL": "e78e9b565cc62813bb829be930758fcb3622426772cb8c67c71bc848ba4f60ac",
    "MTWEAR": "b52f7d560cbb16f972dfa38ead91cb8b6b34c1b04e700170e61db122cc75244d",
    "REWEAR": "2d9c37316d1f5940d4bfc624873a37293e564baba870c81a70d2b9acc5c76142",
    "standby healthy": "e8eabb7b13732b96da0917122c59489663df1ee4a62846dc6ff9a15b088ed217",
    "standby TTS": "73259f9af7e209de6eb36c7716bdcb3a3c63f1c282ad64836ae7a40f888f9753",
    "standby REWEAR": "d86d1e6b06b842175c4459cbaa83080b67788d185ea7ad34b653456072a62f5d",
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
