"""Helpers for the physics tests: short hand-made scenarios run through the real kernel."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from server.vocabulary import POSITIONS
from sim_worker.faults import FaultState, healthy
from sim_worker.fleet import Aircraft
from sim_worker.flight import SimResult, run_scenario
from sim_worker.params import OUT_HZ
from sim_worker.scenario import Scenario

Profile = Callable[[np.ndarray], np.ndarray]


def make_scenario(duration_s: float, x_wl: Profile, x_wt: Profile, f_wl: Profile, f_wt: Profile,
                  t_amb_c: float = 20.0) -> Scenario:
    """Scenario from functions of time: rod commands [m] and loads per actuator [N]."""
    t = np.arange(int(duration_s * OUT_HZ)) / OUT_HZ
    xwl, xwt = x_wl(t), x_wt(t)
    x_cmd = np.ascontiguousarray(np.stack([xwl, xwl, xwt], axis=1))
    f_ext = np.ascontiguousarray(np.stack([f_wl(t), f_wt(t)], axis=1))
    return Scenario(t=t, x_cmd=x_cmd, f_ext=f_ext, t_amb=np.full(t.size, t_amb_c),
                    q=np.ones(t.size))


def ramp(t: np.ndarray, t0: float, t1: float, x0: float, x1: float) -> np.ndarray:
    return np.interp(t, [t0, t1], [x0, x1])


def const(value: float) -> Profile:
    return lambda t: np.full(t.size, value)


def run(aircraft: Aircraft, scenario: Scenario, fault: FaultState | None = None,
        seed: int = 0, active: tuple[str, ...] = POSITIONS) -> SimResult:
    return run_scenario(aircraft, fault or healthy(), scenario, np.random.default_rng(seed),
                        t0_winding_c=float(scenario.t_amb[0]), active=active)
