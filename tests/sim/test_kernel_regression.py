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
    "healthy": "a0080e0434576f3d14320d879b205ad3a80c7998c648095d56f72240790d269e",
    "TTS": "08d58219474aa6347e0f94143193d638d68ad4322ccbce6a3b4b691f46039afb",
    "DMD": "4e4378d5d5cc1c3ad8acb682cb739a2c9bea1e177549335b55a7fc0bc2d33aa7",
    "SE": "4e8bf36b995cc8ed7998763c9e7fe11fe6e8fac4a3588f2f0896dfc81d275e05",
    "BDO": "517810565285da98ef7cb81ccfac1b70f54d981ab5635395986e47f18b5cee4c",
    "MTEL": "c2ad72bf08af66fd02e3686a5022dbdff1e6eecfa331458acaed0b2d5986037e",
    "MTWEAR": "dc8e75e5441a69e5e145bd4f453cf1930f59acaff02bc04b1188fd5343465d6c",
    "REWEAR": "cd5db159d6549d158c06fd7c3060e26c0f6abfba8b648132482f27cebe0cddb1",
    "standby healthy": "2f5f3465056bb42009fa2e4c7c69b22ffd00a76f8e276ae58844d29c6a69cdc8",
    "standby TTS": "2d2d3dbe09eb79c9a50cbc7da7a68828c5e06cf21fa04ff761ea92da5f560a4b",
    "standby REWEAR": "9d906192ffdf24c3eb53cdab1473e6b97624e467f55113b7ffc4a40274fe213c",
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
