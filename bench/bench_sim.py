"""Benchmark of the simulated half-wing: simulated seconds per wall second on one core.

Runs, in one process: (1) one EMA (wingtip drive alone) and (2) the three-EMA half-wing through
the 12 kHz kernel on the reference flight, (3) the motor-only bench kernel and (4)
gym-electric-motor 3.0.3's PMSM environment (``Cont-CC-PMSM-v0``, same motor parameters, same
12 kHz step) on the same motor workload, and reports the ratios. Writes its figures into
``docs/BENCHMARKS.md`` between ``<!-- bench:sim:start -->`` and ``<!-- bench:sim:end -->``.

Usage: ``python bench/bench_sim.py [--seconds 120]``
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from datetime import datetime, timezone
from pathlib import Path

import numpy as np
from _report import cpu_model, replace_block

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

from sim_worker.faults import healthy  # noqa: E402
from sim_worker.fleet import build_aircraft  # noqa: E402
from sim_worker.flight import draw_conditions, run_scenario  # noqa: E402
from sim_worker.kernel import N_ACC, N_DBG, N_SIG, simulate, simulate_motor, warm_up  # noqa: E402
from sim_worker.params import STEP_HZ, MotorParams  # noqa: E402
from sim_worker.scenario import build_scenario  # noqa: E402

DOC = Path(__file__).resolve().parents[1] / "docs" / "BENCHMARKS.md"
START, END = "<!-- bench:sim:start -->", "<!-- bench:sim:end -->"


def _best(fn, repeats: int = 3) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def bench_halfwing(seconds: float) -> tuple[float, float]:
    ac = build_aircraft("I-BENCH1", "Turin", seed=1)
    rng = np.random.default_rng(0)
    cond = draw_conditions(ac, 0, rng)
    sc = build_scenario(cond.warp, cond.ground_temp_c, rng, duration_s=seconds)
    sim_s = float(sc.t.size) / 800.0
    res = run_scenario(ac, healthy(), sc, np.random.default_rng(1))
    par, n = res.params, sc.t.size
    # one EMA: the wingtip drive alone on its surface (surface index 0 in this reduced set)
    par1 = par[2:3].copy()
    par1[0, 24] = 0.0  # P.SURF
    spar3 = np.array([[0.08, 15.0, 2.0], [0.04, 8.0, 1.0]])
    spar1 = spar3[1:2].copy()

    def run(p: np.ndarray, sp: np.ndarray, xcmd: np.ndarray, fext: np.ndarray) -> None:
        m = p.shape[0]
        simulate(p, sp, xcmd, fext, np.ascontiguousarray(sc.t_amb),
                 np.arange(1, m + 1, dtype=np.uint64), np.zeros((n, m, N_SIG)),
                 np.zeros((n, sp.shape[0])), np.zeros((n, m, N_DBG)), np.zeros((m, N_ACC)))

    x1 = np.ascontiguousarray(sc.x_cmd[:, 2:3])
    f1 = np.ascontiguousarray(sc.f_ext[:, 1:2])
    one = _best(lambda: run(par1, spar1, x1, f1))
    three = _best(lambda: run(par, spar3, sc.x_cmd, sc.f_ext))
    return sim_s / one, sim_s / three


def bench_motor_ours(seconds: float) -> float:
    m = MotorParams()
    n = int(seconds * STEP_HZ)
    u = np.zeros((n, 2))
    u[:, 1] = 0.05 * 270.0
    out = np.zeros((n, 3))
    t = _best(lambda: simulate_motor(u, m.r_s_ohm, m.l_d_h, m.l_q_h, m.psi_pm_wb,
                                     float(m.pole_pairs), m.j_kgm2, 2e-4, 0.05, out))
    return seconds / t


def bench_gem(steps: int) -> float:
    import gym_electric_motor as gem

    m = MotorParams()
    env = gem.make(
        "Cont-CC-PMSM-v0", tau=1.0 / STEP_HZ, visualization=[],
        motor=dict(motor_parameter=dict(p=m.pole_pairs, l_d=m.l_d_h, l_q=m.l_q_h,
                                        j_rotor=m.j_kgm2, r_s=m.r_s_ohm, psi_p=m.psi_pm_wb),
                   limit_values=dict(i=60, u=270, omega=3000),
                   nominal_values=dict(i=17, u=270, omega=2500)),
        supply=dict(u_nominal=270))
    env.reset(seed=0)
    action = np.full(env.action_space.shape, 0.05)
    t0 = time.perf_counter()
    for _ in range(steps):
        _obs, _r, term, trunc, _info = env.step(action)
        if term or trunc:
            env.reset()
    return steps / STEP_HZ / (time.perf_counter() - t0)


def write_block(text: str) -> None:
    replace_block(START, END, text)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=120.0, help="simulated seconds per run")
    ap.add_argument("--gem-steps", type=int, default=24000, help="gym-electric-motor steps")
    args = ap.parse_args()
    load = os.getloadavg()[0]  # the cores may be shared: figures drop with other jobs' load
    warm_up()
    one, three = bench_halfwing(args.seconds)
    motor = bench_motor_ours(args.seconds)
    gem_rt = bench_gem(args.gem_steps)
    now = datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    text = f"""## Simulator (bench/bench_sim.py)

Machine: {cpu_model()}, {os.cpu_count()} cores, Python {platform.python_version()}, {now};
load average {load:.1f} at the start.
One core (numba kernel, single thread), fixed step {STEP_HZ / 1000:.0f} kHz, best of 3 runs of
{args.seconds:.0f} s simulated; gym-electric-motor 3.0.3 `Cont-CC-PMSM-v0` with the same motor
parameters and step, {args.gem_steps} steps.

| workload | simulated s per wall s (x real time) |
|---|---|
| one EMA (motor, inverter, 3 loops, screw, backlash, surface, thermal, sensors) | {one:,.0f} |
| half-wing, three EMAs and two surfaces | {three:,.0f} (= {3 * three:,.0f} per EMA) |
| PMSM only, our bench kernel (`simulate_motor`) | {motor:,.0f} |
| PMSM only, gym-electric-motor env | {gem_rt:,.2f} |

Ratios: one full EMA / gym-electric-motor PMSM = **{one / gem_rt:,.0f}x**; PMSM only, ours /
gym-electric-motor = **{motor / gem_rt:,.0f}x**. Targets: >= 1000x real time per EMA,
>= 100x gym-electric-motor.
"""
    write_block(text)
    print(text)


if __name__ == "__main__":
    main()
