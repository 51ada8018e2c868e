"""Benchmark of a streamed campaign flight: where a flight's time goes, and what the paper
protocol costs on this machine.

One process, one core: ``--flights`` flights of the protocol scale's recording length are
simulated (12 kHz half-wing), written to the flight-log contract in memory (Parquet bytes),
decoded and checked as an upload, and their features computed: the four stages of
:class:`server.campaigns.FeatureSink`. The expected number of flights of the protocol's
design and verification campaigns (every flight of every pattern, expected spans) turns the
per-flight time into campaign hours per core and on ``--workers`` cores. Writes its figures
into ``docs/BENCHMARKS.md`` between ``<!-- bench:campaign:start -->`` and
``<!-- bench:campaign:end -->``.

Usage: ``python bench/bench_campaign.py [--flights 12] [--workers 2]``
"""

from __future__ import annotations

import argparse
import os
import time
from datetime import datetime, timezone

import numpy as np
from _report import cpu_model, replace_block

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

from server.campaigns import decode_channels  # noqa: E402
from server.flightlog import write_parquet  # noqa: E402
from server.phm.features import FeatureConfig, flight_features  # noqa: E402
from sim_worker.campaign import SCALES, fleet_for, plan_campaign  # noqa: E402
from sim_worker.faults import PROGRESSIVE, healthy  # noqa: E402
from sim_worker.flight import flight_start, simulate_flight  # noqa: E402
from sim_worker.kernel import warm_up  # noqa: E402

START, END = "<!-- bench:campaign:start -->", "<!-- bench:campaign:end -->"
STAGES = ("simulate", "write", "decode", "features")


def time_flights(n: int, duration_s: float) -> dict[str, np.ndarray]:
    """Seconds per stage for ``n`` healthy protocol flights on verification aircraft."""
    fleet = fleet_for("verification", 2)
    out = {s: np.empty(n) for s in STAGES}
    cfg = FeatureConfig()
    for i in range(n):
        aircraft = fleet[i % len(fleet)]
        t0 = time.perf_counter()
        log, summary = simulate_flight(aircraft, healthy(), i, np.random.default_rng([7, i]),
                                       flight_id=f"B-{i:04d}", started_at=flight_start(i),
                                       duration_s=duration_s)
        t1 = time.perf_counter()
        data = write_parquet(log)
        t2 = time.perf_counter()
        channels = decode_channels(data, f"B-{i:04d}")
        t3 = time.perf_counter()
        flight_features(channels, config=cfg, ground_temp_c=float(summary.ground_temp_c))
        t4 = time.perf_counter()
        for s, dt in zip(STAGES, (t1 - t0, t2 - t1, t3 - t2, t4 - t3), strict=True):
            out[s][i] = dt
    return out


def expected_flights(kind: str) -> float:
    """Flights of a protocol campaign, fault-to-failure runs at their mean expected span."""
    cfg = SCALES["protocol"][kind]
    span = float(np.mean(cfg.span_flights))
    total = 0.0
    for spec in plan_campaign(kind, 0, "protocol"):
        total += (cfg.lead_flights + span + 1) if spec.mode in PROGRESSIVE else spec.n_flights
    return total


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--flights", type=int, default=12)
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    duration = SCALES["protocol"]["verification"].duration_s
    warm_up()
    time_flights(1, duration)  # first-call costs (imports, caches) out of the figures
    t = time_flights(args.flights, duration)
    per = {s: float(np.median(v)) for s, v in t.items()}
    flight_s = sum(per.values())
    load = os.getloadavg()[0]
    rows = [f"| {s} | {1000 * per[s]:.0f} | {100 * per[s] / flight_s:.0f} % |" for s in STAGES]
    n_ver = expected_flights("verification")
    budget = 2 * 3600 * args.workers / n_ver  # s per flight for the verification in 2 hours
    sim_needed = budget - (flight_s - per["simulate"])
    camp = []
    for kind in ("design", "verification"):
        n = expected_flights(kind)
        camp.append(f"| {kind} | {n:,.0f} | {n * flight_s / 3600:.1f} | "
                    f"{n * flight_s / 3600 / args.workers:.1f} |")
    text = "\n".join([
        "## Streamed campaign flight (`bench/bench_campaign.py`)",
        "",
        f"{datetime.now(timezone.utc):%Y-%m-%d}, {cpu_model()}, one core, load {load:.1f}; "
        f"median of {args.flights} healthy flights of {duration:.0f} s of actuator activity "
        "(the protocol's recordings), each through the four stages of a streamed flight:",
        "",
        "| stage | ms per flight | share |",
        "|---|---|---|",
        *rows,
        f"| **flight** | **{1000 * flight_s:.0f}** | |",
        "",
        f"Protocol campaigns at that rate (fault-to-failure runs at their mean expected span, "
        f"{np.mean(SCALES['protocol']['verification'].span_flights):.0f} flights; "
        f"{args.workers} workers scale linearly, patterns being independent):",
        "",
        f"| campaign | flights | hours on one core | hours on {args.workers} cores |",
        "|---|---|---|---|",
        *camp,
        "",
        f"The verification campaign within 2 hours on {args.workers} cores needs "
        f"{1000 * budget:.0f} ms per flight: with the other stages as they are, the simulator "
        f"at {1000 * sim_needed:.0f} ms, {per['simulate'] / sim_needed:.1f} times its speed.",
        "",
        f"Command: `python bench/bench_campaign.py --flights {args.flights} "
        f"--workers {args.workers}`",
    ])
    print(text)
    replace_block(START, END, text)


if __name__ == "__main__":
    main()
