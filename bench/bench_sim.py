"""Benchmark of the simulated half-wing: simulated seconds per second of one core.

Runs, in one process: (1) one EMA (wingtip drive alone) and (2) the three-EMA half-wing through
the 12 kHz kernel on the reference flight, one flight a call (a batch of one), then (3) the
half-wing in lanes, 4, 8 and 16 flights a call, (4) the motor-only bench kernel and (5)
gym-electric-motor 3.0.3's PMSM environment (``Cont-CC-PMSM-v0``, same motor parameters, same
12 kHz step) on the same motor workload, and reports the ratios. Each figure is the best of 3
runs by the process's CPU time (the kernel is single-threaded; on a shared machine the wall
time also counts the other jobs' share of the core), with the wall time beside it. Writes its
figures into ``docs/BENCHMARKS.md`` between ``<!-- bench:sim:start -->`` and
``<!-- bench:sim:end -->``.

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
from sim_worker.flight import draw_conditions, kernel_inputs, run_kernels  # noqa: E402
from sim_worker.kernel import (  # noqa: E402
    N_ACC,
    N_DBG,
    N_SIG,
    simulate,
    simulate_motor,
    warm_up,
)
from sim_worker.params import STEP_HZ, MotorParams, P  # noqa: E402
from sim_worker.scenario import build_scenario  # noqa: E402

DOC = Path(__file__).resolve().parents[1] / "docs" / "BENCHMARKS.md"
START, END = "<!-- bench:sim:start -->", "<!-- bench:sim:end -->"


LANES = (4, 8, 16)


def _best(fn, repeats: int = 3) -> tuple[float, float]:
    """Best CPU time and best wall time [s] of ``repeats`` runs."""
    cpu, wall = [], []
    for _ in range(repeats):
        c0, w0 = time.process_time(), time.perf_counter()
        fn()
        cpu.append(time.process_time() - c0)
        wall.append(time.perf_counter() - w0)
    return min(cpu), min(wall)


def bench_halfwing(seconds: float) -> dict[str, tuple[float, float]]:
    """x real time (CPU, wall) of one EMA, of the half-wing one flight a call, and per EMA of
    the half-wing in lanes (keys ``"one"``, ``"halfwing"``, lane counts)."""
    ac = build_aircraft("I-BENCH1", "Turin", seed=1)
    rng = np.random.default_rng(0)
    cond = draw_conditions(ac, 0, rng)
    sc = build_scenario(cond.warp, cond.ground_temp_c, rng, duration_s=seconds)
    sim_s = float(sc.t.size) / 800.0
    flights = [kernel_inputs(ac, healthy(), sc, np.random.default_rng(i + 1))
               for i in range(max(LANES))]
    n = sc.t.size
    # one EMA: the wingtip drive alone on its surface (surface index 0 in this reduced set)
    par1 = flights[0].params[2:3, :, None].copy()
    par1[0, P.SURF, 0] = 0.0
    spar1 = flights[0].surfaces[1:2, :, None].copy()

    def one() -> None:
        simulate(par1, spar1, np.ascontiguousarray(sc.x_cmd[:, 2:3, None]),
                 np.ascontiguousarray(sc.f_ext[:, 1:2, None]), sc.t_amb[:, None].copy(),
                 np.ones((1, 1), dtype=np.uint64), np.full(1, n), np.empty((1, n, 1, N_SIG)),
                 np.empty((1, n, 1)), np.empty((1, 0, 1, N_DBG)), np.empty((1, 1, N_ACC)))

    out = {"one": tuple(sim_s / t for t in _best(one))}
    out["halfwing"] = tuple(sim_s / t for t in _best(lambda: run_kernels(flights[:1],
                                                                          truth=False)))
    for lanes in LANES:
        batch = flights[:lanes]
        out[str(lanes)] = tuple(3 * lanes * sim_s / t
                                for t in _best(lambda b=batch: run_kernels(b, truth=False)))
    return out  # type: ignore[return-value]


def bench_motor_ours(seconds: float) -> float:
    m = MotorParams()
    n = int(seconds * STEP_HZ)
    u = np.zeros((n, 2))
    u[:, 1] = 0.05 * 270.0
    out = np.zeros((n, 3))
    t, _ = _best(lambda: simulate_motor(u, m.r_s_ohm, m.l_d_h, m.l_q_h, m.psi_pm_wb,
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
    t0 = time.process_time()
    for _ in range(steps):
        _obs, _r, term, trunc, _info = env.step(action)
        if term or trunc:
            env.reset()
    return steps / STEP_HZ / (time.process_time() - t0)


def write_block(text: str) -> None:
    replace_block(START, END, text)


def _flags() -> str:
    """The SIMD extensions the CPU offers (what numba compiles the kernel for)."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("flags"):
                have = set(line.split(":", 1)[1].split())
                return " ".join(f for f in ("fma", "avx2", "avx512f", "avx512dq", "avx512vl")
                                if f in have)
    except OSError:
        pass
    return "unknown"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=120.0, help="simulated seconds per run")
    ap.add_argument("--gem-steps", type=int, default=24000, help="gym-electric-motor steps")
    ap.add_argument("--note", default="", help="what else ran on the machine meanwhile")
    args = ap.parse_args()
    load = os.getloadavg()[0]  # the cores may be shared: figures drop with other jobs' load
    warm_up()
    sim = bench_halfwing(args.seconds)
    motor = bench_motor_ours(args.seconds)
    gem_rt = bench_gem(args.gem_steps)
    load_end = os.getloadavg()[0]
    now = datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    one, half = sim["one"], sim["halfwing"]
    lanes_rows = "\n".join(
        f"| half-wing in lanes, {n} flights a call | {sim[str(n)][0]:,.0f} per EMA "
        f"({sim[str(n)][0] / (3 * half[0]):.2f}x one flight a call) | {sim[str(n)][1]:,.0f} |"
        for n in LANES)
    note = f"\n{args.note}" if args.note else ""
    rows = "\n".join([
        "| one EMA (motor, inverter, 3 loops, screw, backlash, surface, thermal, sensors) | "
        f"{one[0]:,.0f} | {one[1]:,.0f} |",
        "| half-wing, three EMAs and two surfaces, one flight a call | "
        f"{half[0]:,.0f} (= {3 * half[0]:,.0f} per EMA) | {half[1]:,.0f} |",
        lanes_rows])
    text = f"""## Simulator (bench/bench_sim.py)

Machine: {cpu_model()}, {os.cpu_count()} cores, SIMD {_flags()}, Python
{platform.python_version()}, {now}; load average {load:.1f} at the start, {load_end:.1f} at
the end.{note}
One core (numba kernel, single thread), fixed step {STEP_HZ / 1000:.0f} kHz, best of 3 runs of
{args.seconds:.0f} s simulated, by the process's CPU time (wall time beside it: it also counts
other jobs' share of the core); gym-electric-motor 3.0.3 `Cont-CC-PMSM-v0` with the same motor
parameters and step, {args.gem_steps} steps.

| workload | x real time, CPU | x real time, wall |
|---|---|---|
{rows}
| PMSM only, our bench kernel (`simulate_motor`) | {motor:,.0f} | |
| PMSM only, gym-electric-motor env | {gem_rt:,.2f} | |

Ratios: one full EMA / gym-electric-motor PMSM = **{one[0] / gem_rt:,.0f}x**; PMSM only, ours /
gym-electric-motor = **{motor / gem_rt:,.0f}x**; the half-wing in 8 lanes = **{sim["8"][0]:,.0f}x
real time per EMA-core**. Targets: >= 3000x real time per EMA-core, >= 100x
gym-electric-motor.
"""
    write_block(text)
    print(text)


if __name__ == "__main__":
    main()
