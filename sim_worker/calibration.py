"""Measure the worn drive's load share of an active-active winglet pair (``data/load_share.json``,
see :mod:`.load_share`).

For each wear mode and position, the same flights (same conditions, gusts and sensor seeds) are
simulated at 12 kHz at a grid of normalised severities; the ratio of the faulty drive's summed
simulated work to its summed quasi-static estimate is the load share at that severity. The
flights are flown by a calibration fleet whose tails and seeds are neither design nor
verification ones. ``sim-worker load-share --out sim_worker/data/load_share.json`` regenerates
the table; it must be re-run whenever the kernel or the scenario changes.
"""

from __future__ import annotations

from concurrent.futures import ProcessPoolExecutor
from datetime import datetime, timezone
from typing import Any

import numpy as np

from server.vocabulary import POSITIONS

from .faults import THRESHOLDS, FaultState, healthy
from .fleet import BASES, WingletMode, build_aircraft
from .flight import (
    _summary_from_acc,
    build_scenario,
    draw_conditions,
    estimate_summary,
    flight_start,
    run_scenario,
)
from .load_share import WORK_FIELD

__all__ = ["measure_load_share", "SEVERITY_GRID"]

SEVERITY_GRID: tuple[float, ...] = (0.0, 0.05, 0.1, 0.15, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8,
                                    0.9, 1.0, 1.2)
_CALIBRATION_SEED = 4242


def _fleet(n: int) -> list:
    bases = sorted(BASES)
    return [build_aircraft(f"I-CAL{i:02d}", bases[i % len(bases)],
                           int(np.random.SeedSequence([_CALIBRATION_SEED, i]).generate_state(1)[0]))
            for i in range(n)]


def _curve(args: tuple[str, str, tuple[float, ...], int, float]) -> list[float]:
    mode, position, grid, n_flights, duration_s = args
    field = WORK_FIELD[mode]
    fleet = _fleet(min(n_flights, 6))
    simulated = np.zeros(len(grid))
    estimated = 0.0
    for j in range(n_flights):
        aircraft = fleet[j % len(fleet)]
        index = 37 * j  # spread the flights over the seasons
        seed = [_CALIBRATION_SEED, j]  # the same conditions, gusts and noise at every severity
        est = estimate_summary(aircraft, index, np.random.default_rng(seed),
                               started_at=flight_start(index), duration_s=duration_s,
                               winglet_mode=WingletMode.ACTIVE_ACTIVE)
        estimated += getattr(est.actuators[position], field)
        for k, s_n in enumerate(grid):
            fault = healthy() if s_n == 0.0 else FaultState(
                mode, position, s_n * THRESHOLDS[mode], THRESHOLDS[mode])
            r = np.random.default_rng(seed)
            cond = draw_conditions(aircraft, index, r, started_at=flight_start(index))
            scenario = build_scenario(cond.warp, cond.ground_temp_c, r, duration_s=duration_s)
            res = run_scenario(aircraft, fault, scenario, r)
            summ = _summary_from_acc(res.acc, cond, duration_s)
            simulated[k] += getattr(summ.actuators[position], field)
    return [round(float(v), 4) for v in simulated / estimated]


def measure_load_share(*, n_flights: int = 12, duration_s: float = 60.0,
                       grid: tuple[float, ...] = SEVERITY_GRID, workers: int | None = None,
                       modes: tuple[str, ...] = tuple(WORK_FIELD),
                       positions: tuple[str, ...] = POSITIONS) -> dict[str, Any]:
    """The load-share table (``ema-load-share/1``): per mode and position, simulated over
    estimated work of the faulty drive at each normalised severity of ``grid``."""
    if n_flights < 1:
        raise ValueError("n_flights must be at least 1")
    if not grid or grid[0] != 0.0 or any(b <= a for a, b in zip(grid, grid[1:], strict=False)):
        raise ValueError("grid must start at 0 and increase")
    tasks = [(m, p, tuple(grid), n_flights, duration_s) for m in modes for p in positions]
    if workers == 1:
        curves = list(map(_curve, tasks))
    else:
        with ProcessPoolExecutor(max_workers=workers) as pool:
            curves = list(pool.map(_curve, tasks))
    ratio: dict[str, dict[str, list[float]]] = {m: {} for m in modes}
    for (m, p, *_), curve in zip(tasks, curves, strict=True):
        ratio[m][p] = curve
    return {
        "format": "ema-load-share/1",
        "measured_at": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "method": f"{n_flights} paired flights of {duration_s:g} s per point, calibration fleet "
                  f"seed {_CALIBRATION_SEED}; ratio of summed simulated to summed estimated "
                  "work of the faulty drive",
        "severity_norm": list(grid),
        "ratio": ratio,
    }
