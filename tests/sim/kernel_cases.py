"""Kernel inputs of short flights covering what a lane can differ in: every fault mode, both
winglet modes, sensor injections, station conditions, an open MOSFET on each leg and side, and
lengths from 1.5 to 3 s; with the sha256 digests of the outputs the scalar kernel (one flight a
call, before the kernel ran flights in lanes) gave for each, recorded on this project's
reference machine (see tests/sim/test_kernel_regression.py for what the digests depend on);
tests/sim/test_kernel_lanes.py holds every lane of the kernel in lanes to them.

Run ``python tests/sim/kernel_cases.py`` to print the digests of the kernel as it is now.
"""

from __future__ import annotations

import hashlib
from dataclasses import replace

import numpy as np

from sim_worker.conditions import NO_CONDITIONS, Conditions
from sim_worker.faults import FaultState, fault_at
from sim_worker.fleet import WingletMode, active_channels, build_aircraft
from sim_worker.flight import KernelInputs, SimResult, imposed_conditions, kernel_inputs
from sim_worker.params import P
from sim_worker.scenario import CRUISE_TEMP_C, build_scenario
from sim_worker.sensors import SensorInjection, degrade

AA, AS = WingletMode.ACTIVE_ACTIVE, WingletMode.ACTIVE_STANDBY


def _fault(mode: str, position: str | None = None, severity_norm: float = 0.7) -> FaultState:
    return fault_at(mode, position, severity_norm, phase_rad=1.0 if mode == "SE" else 0.0)


def _inj(position: str, sensor: str, kind: str, value: float) -> SensorInjection:
    return SensorInjection(1, position, sensor, kind, value, 0)


#: name: (fault, winglet mode, flight index, duration [s], sensor injections, conditions,
#: open-MOSFET override (leg, upper) or None)
CASES: dict[str, tuple] = {
    "healthy": (_fault("healthy"), AA, 0, 3.0, (), NO_CONDITIONS, None),
    "TTS": (_fault("TTS", "WL1", 0.6), AA, 0, 2.5, (), NO_CONDITIONS, None),
    "DMD": (_fault("DMD", "WT", 0.6), AA, 0, 2.0, (), NO_CONDITIONS, None),
    "SE": (_fault("SE", "WL2", 0.6), AA, 0, 3.0, (), NO_CONDITIONS, None),
    "BDO": (_fault("BDO", "WT", 1.0), AA, 0, 1.5, (), NO_CONDITIONS, None),
    "BDO leg b lower": (_fault("BDO", "WL1", 1.0), AA, 0, 2.0, (), NO_CONDITIONS, (1, 0.0)),
    "BDO leg c upper": (_fault("BDO", "WL2", 1.0), AA, 0, 2.0, (), NO_CONDITIONS, (2, 1.0)),
    "MTEL": (_fault("MTEL", "WL1"), AA, 0, 2.5, (), NO_CONDITIONS, None),
    "MTWEAR": (_fault("MTWEAR", "WL2"), AA, 0, 3.0, (), NO_CONDITIONS, None),
    "REWEAR": (_fault("REWEAR", "WT"), AA, 0, 2.0, (), NO_CONDITIONS, None),
    "standby healthy": (_fault("healthy"), AS, 0, 2.5, (), NO_CONDITIONS, None),
    "standby TTS": (_fault("TTS", "WL2", 0.6), AS, 0, 2.0, (), NO_CONDITIONS, None),
    "standby BDO": (_fault("BDO", "WL1", 1.0), AS, 1, 2.0, (), NO_CONDITIONS, None),
    "standby SE": (_fault("SE", "WL1", 0.6), AS, 1, 1.5, (), NO_CONDITIONS, None),
    "standby REWEAR": (_fault("REWEAR", "WL1"), AS, 1, 3.0, (), NO_CONDITIONS, None),
    "resolver stuck": (_fault("healthy"), AA, 0, 2.0,
                       (_inj("WT", "resolver", "stuck", 0.3),), NO_CONDITIONS, None),
    "clipped I, noisy V": (
        _fault("healthy"), AA, 0, 2.5,
        (_inj("WL1", "current", "clipped", 2.0), _inj("WL2", "voltage", "noise", 3.0)),
        NO_CONDITIONS, None),
    "lvdt drift and coarse": (
        _fault("healthy"), AS, 0, 2.0,
        (_inj("WL1", "lvdt", "drift", 2e-4), _inj("WT", "lvdt", "quantisation", 1e-4)),
        NO_CONDITIONS, None),
    "hot, loaded, small x": (
        _fault("MTEL", "WT"), AA, 0, 2.5, (),
        Conditions(ambient_offset_k=15.0, load_scale=1.6, load_offset_n=300.0,
                   command_scale=0.7), None),
    "cold, large x, standby": (
        _fault("TTS", "WL1", 0.5), AS, 1, 2.0, (),
        Conditions(ambient_offset_k=-20.0, command_scale=1.4), None),
}


def case_inputs(name: str) -> KernelInputs:
    """The kernel inputs of case ``name``, drawn as a flight of the station draws them."""
    fault, mode, flight, duration, injections, conditions, bdo = CASES[name]
    aircraft = degrade(build_aircraft("I-LANE01", "Turin", seed=2026), list(injections),
                       flight)
    rng = np.random.default_rng([53, flight, int(duration * 10)])
    cond = imposed_conditions(aircraft, flight, rng, conditions)
    scenario = build_scenario(cond.warp, cond.ground_temp_c, rng, duration_s=duration,
                              cruise_temp_c=CRUISE_TEMP_C + conditions.ambient_offset_k)
    inp = kernel_inputs(aircraft, fault, scenario, rng, active=active_channels(mode, flight))
    if bdo is not None:
        par = inp.params.copy()
        k = ("WL1", "WL2", "WT").index(fault.position)
        par[k, P.BDO_LEG], par[k, P.BDO_UPPER] = bdo
        inp = replace(inp, params=par)
    return inp


def digest(res: SimResult) -> str:
    """sha256 of a run's float64 outputs: signals, surfaces, true states, accumulators."""
    h = hashlib.sha256()
    for a in (res.signals, res.surfaces, res.truth, res.acc):
        h.update(np.ascontiguousarray(a, dtype="<f8").tobytes())
    return h.hexdigest()


#: the scalar kernel's digests (one flight a call), recorded before the kernel ran in lanes
SCALAR_DIGESTS: dict[str, str] = {
    "healthy": "4fb1f4b07585b39e815999f79031b7fe62ef62fa97d05e5201e95ebfd4435725",
    "TTS": "1ce638515ebbe995d46062fe3737e2c678f18f86a0403eba375beb7f4dee912b",
    "DMD": "4f1267f0f64ca0219cc61219fbe8181a83df5e5bd60cc6b9eb6d7cf3f78192a3",
    "SE": "3ac28c61b2e68e193c540351136e1c9e50d14e52d7e8034ea2abea825fd7f46d",
    "BDO": "1d5009ec1ed9afe1ff901e91f41d4003e94bbac36059fb8610e4260f2a9fd0f5",
    "BDO leg b lower": "05785f3d9c8e1459ef33c1ac710320b87d7bdb7dff807e6142022c2af2ff1211",
    "BDO leg c upper": "923f70c9f4fd866a7decc7336fecf7aca105f0eb4253f4514cbf3567c4a58eac",
    "MTEL": "bfa60c545a77a17ba6a5cd4ac7e1e99feced9869a59427eb3e1d0e6945c82b20",
    "MTWEAR": "61e26ac05a0b471e51c58b4386623232137622c8ecf72486048662705c2ff6c1",
    "REWEAR": "8f95269c9e281ab3d4374899d1b3a6ecb8ebab3ae81c800a1ca313fa645fda6f",
    "standby healthy": "f872a27722762a51bba3a5adc2a5ea487cc864aca1ecc0fac61a83f8651a41c5",
    "standby TTS": "8f9b0cef55898ec84ca93204470e977a1b88b7db9c6ba0f5d1896dcfaa0cd741",
    "standby BDO": "58282c2437d5c6062fd1a64e1a8071a44d6a3a93e26508585b898c49259d06cc",
    "standby SE": "92296342903d447ffe38eb88f2dbfdc78e13387f9af51037b55318fd43c54089",
    "standby REWEAR": "a8e697e3f9062c63340458e8a910aece988f9834e2257ed5409af4205b8a3c77",
    "resolver stuck": "746d973fbfcc4da78965f3c19be56a8fd708d2af67b30fe905edf7c630338a98",
    "clipped I, noisy V": "b848a6b1ff9081db9b1326fabbdbc55dd0a028086e5460d349f0916309912d24",
    "lvdt drift and coarse": "b766a4c313256f8506c6708f3637d16d0a41329eb321d04bb21668fb5a973f47",
    "hot, loaded, small x": "67af8d1bf0f7b938b120edcfbbc3307d904a9aa93448fb8c949720a20646035b",
    "cold, large x, standby": "b6907e00ce50b3f02c69657aea4189b3fb5519f0af3b53c88ec12943b46516fa",
}


if __name__ == "__main__":
    from sim_worker.flight import run_kernel

    print("SCALAR_DIGESTS: dict[str, str] = {")
    for case in CASES:
        print(f'    "{case}": "{digest(run_kernel(case_inputs(case)))}",')
    print("}")
