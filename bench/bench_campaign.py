"""Benchmark of a streamed campaign flight: where a flight's time goes, and what the paper
protocol costs on this machine.

One process, one core: ``--flights`` flights of the protocol scale's recording length are
simulated (12 kHz half-wing), checked as an upload and their features computed, the stages of
:class:`server.campaigns.FeatureSink` for a flight whose log is dropped (no Parquet round
trip); a kept flight (every ``keep_raw_every``-th of a pattern, 200 by default) also has its
log written to Parquet and decoded from those bytes, timed on every flight and charged to a
flight at the campaigns' share of kept flights. The expected number of flights of the
protocol's design and verification campaigns (every flight of every pattern, expected spans)
turns the per-flight time into campaign hours per core and on ``--workers`` cores. Writes its
figures into ``docs/BENCHMARKS.md`` between ``<!-- bench:campaign:start -->`` and
``<!-- bench:campaign:end -->``.

Usage: ``python bench/bench_campaign.py [--flights 16] [--lanes 8] [--workers 2]``
"""

from __future__ import annotations

import argparse
import math
import os
import time
from datetime import datetime, timezone

import numpy as np
from _report import cpu_model, replace_block

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

from server.campaigns import checked_log, decode_log  # noqa: E402
from server.flightlog import write_parquet  # noqa: E402
from server.phm.features import FeatureConfig  # noqa: E402
from server.phm.recording import log_features  # noqa: E402
from sim_worker.campaign import SCALES, fleet_for, plan_campaign  # noqa: E402
from sim_worker.faults import PROGRESSIVE, healthy  # noqa: E402
from sim_worker.flight import LANES, FlightSpec, flight_start, simulate_flights  # noqa: E402
from sim_worker.kernel import warm_up  # noqa: E402

START, END = "<!-- bench:campaign:start -->", "<!-- bench:campaign:end -->"
STAGES = ("simulate", "check", "features")
KEPT = ("write", "decode")  # a kept flight's Parquet round trip, in place of "check"
KEEP_RAW_EVERY = 200  # the campaign commands' default


def time_flights(n: int, duration_s: float, lanes: int) -> dict[str, np.ndarray]:
    """Seconds per stage for ``n`` healthy protocol flights on verification aircraft, simulated
    ``lanes`` at a time as a campaign's patterns fly in lockstep (each flight charged its
    share of its kernel call)."""
    fleet = fleet_for("verification", 2)
    out = {s: np.empty(n) for s in STAGES + KEPT}
    cfg = FeatureConfig()
    specs = [FlightSpec(fleet[i % len(fleet)], healthy(), i, np.random.default_rng([7, i]),
                        flight_id=f"B-{i:04d}", started_at=flight_start(i),
                        duration_s=duration_s) for i in range(n)]
    flown = []
    for b in range(0, n, lanes):
        t0 = time.perf_counter()
        batch = simulate_flights(specs[b:b + lanes], lanes=lanes)
        share = (time.perf_counter() - t0) / len(batch)
        flown += [(log, summary, share) for log, summary in batch]
    for i, (log, summary, share) in enumerate(flown):
        t1 = time.perf_counter()
        t0 = t1 - share
        checked = checked_log(log, f"B-{i:04d}")
        t2 = time.perf_counter()
        log_features(checked, config=cfg, ground_temp_c=float(summary.ground_temp_c))
        t3 = time.perf_counter()
        data = write_parquet(log)
        t4 = time.perf_counter()
        decode_log(data, f"B-{i:04d}")
        t5 = time.perf_counter()
        for s, dt in zip(STAGES + KEPT, (t1 - t0, t2 - t1, t3 - t2, t4 - t3, t5 - t4),
                         strict=True):
            out[s][i] = dt
    return out


def expected_flights(kind: str) -> tuple[float, float]:
    """Flights of a protocol campaign, fault-to-failure runs at their mean expected span, and
    how many of them keep their logs (index 0 and every ``KEEP_RAW_EVERY``-th of a pattern)."""
    cfg = SCALES["protocol"][kind]
    span = float(np.mean(cfg.span_flights))
    total = kept = 0.0
    for spec in plan_campaign(kind, 0, "protocol"):
        n = (cfg.lead_flights + span + 1) if spec.mode in PROGRESSIVE else spec.n_flights
        total += n
        kept += math.ceil(n / KEEP_RAW_EVERY)
    return total, kept


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--flights", type=int, default=16)
    ap.add_argument("--lanes", type=int, default=LANES,
                    help="flights per kernel call (1: one flight at a time)")
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    duration = SCALES["protocol"]["verification"].duration_s
    warm_up()
    time_flights(args.lanes, duration, args.lanes)  # first-call costs out of the figures
    t = time_flights(args.flights, duration, args.lanes)
    per = {s: float(np.median(v)) for s, v in t.items()}
    counts = {kind: expected_flights(kind) for kind in ("design", "verification")}
    kept_share = sum(k for _, k in counts.values()) / sum(n for n, _ in counts.values())
    # a kept flight pays the round trip in place of the in-memory check
    kept_extra = max(per["write"] + per["decode"] - per["check"], 0.0)
    flight_s = sum(per[s] for s in STAGES) + kept_share * kept_extra
    load = os.getloadavg()[0]
    rows = [f"| {s} | {1000 * per[s]:.1f} | {100 * per[s] / flight_s:.0f} % |" for s in STAGES]
    n_ver = counts["verification"][0]
    n_all = n_ver + counts["design"][0]
    budget = 2 * 3600 * args.workers / n_ver  # s per flight for the verification in 2 hours
    budget_all = 2 * 3600 * args.workers / n_all  # both campaigns in 2 hours
    camp = []
    for kind, (n, kept) in counts.items():
        camp.append(f"| {kind} | {n:,.0f} | {kept:,.0f} | {n * flight_s / 3600:.1f} | "
                    f"{n * flight_s / 3600 / args.workers:.1f} |")
    sim_rt = duration / per["simulate"]
    text = "\n".join([
        "## Streamed campaign flight (`bench/bench_campaign.py`)",
        "",
        f"{datetime.now(timezone.utc):%Y-%m-%d}, {cpu_model()}, one core, load {load:.1f}; "
        f"median of {args.flights} healthy flights of {duration:.0f} s of actuator activity, "
        f"simulated {args.lanes} per kernel call "
        "(the protocol's recordings), each through the stages of a streamed flight whose log "
        "is dropped (checked as an upload in memory, no Parquet round trip):",
        "",
        "| stage | ms per flight | share |",
        "|---|---|---|",
        *rows,
        f"| kept flights' Parquet round trip (write {1000 * per['write']:.0f} ms + decode "
        f"{1000 * per['decode']:.0f} ms in place of the check), at "
        f"{100 * kept_share:.1f} % of the flights | {1000 * kept_share * kept_extra:.1f} | "
        f"{100 * kept_share * kept_extra / flight_s:.0f} % |",
        f"| **flight** | **{1000 * flight_s:.0f}** | |",
        "",
        f"The simulator runs {sim_rt:,.0f}x real time on the half-wing "
        f"({3 * sim_rt:,.0f}x per EMA).",
        "",
        f"Protocol campaigns at that rate (fault-to-failure runs at their mean expected span, "
        f"{np.mean(SCALES['protocol']['verification'].span_flights):.0f} flights; logs kept "
        f"every {KEEP_RAW_EVERY} flights of a pattern; {args.workers} workers scale linearly, "
        "patterns being independent):",
        "",
        f"| campaign | flights | logs kept | hours on one core | hours on {args.workers} cores |",
        "|---|---|---|---|---|",
        *camp,
        "",
        f"Within 2 hours on {args.workers} cores, the verification campaign needs "
        f"{1000 * budget:.0f} ms per flight ({flight_s / budget:.2f} times that is spent) "
        f"and both campaigns {1000 * budget_all:.0f} ms ({flight_s / budget_all:.2f} times).",
        "",
        f"Command: `python bench/bench_campaign.py --flights {args.flights} "
        f"--lanes {args.lanes} --workers {args.workers}`",
    ])
    print(text)
    replace_block(START, END, text)


if __name__ == "__main__":
    main()
