# ruff: noqa: E501  (the Markdown table rows of the report are long)
"""Load test of the production topology on loopback: API process + 2 worker processes +
PostgreSQL (a fresh database, dropped afterwards).

Concurrent uploaders (threads) each send their own aircraft's flights (every upload a distinct
(aircraft, flight) made by ``tests.flightlog_factory``); the test measures upload latency
(p50/p95), analysis throughput (flights per minute, and per worker) and checks that no flight
was lost or duplicated (database counts against accepted uploads). Bounded in count and time:
it stops by itself. Figures go to docs/BENCHMARKS.md between the ``bench:load`` markers.

    .venv/bin/python bench/load_test.py            # 8 uploaders x 25 flights, 2 workers
    .venv/bin/python bench/load_test.py --uploaders 4 --flights 10 --no-write
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import platform
import statistics
import sys
import tempfile
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import httpx
from _report import BENCHMARKS, cpu_model, replace_block

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from sqlalchemy import create_engine, func, select  # noqa: E402
from sqlalchemy.orm import Session  # noqa: E402

from server.config import Settings  # noqa: E402
from server.models import Flight, HealthRecord, Job  # noqa: E402
from server.vocabulary import FlightStatus, JobStatus  # noqa: E402
from tests.flightlog_factory import make_parquet, serials_for  # noqa: E402
from tests.live_server import running_server  # noqa: E402
from tests.production.helpers import (  # noqa: E402
    env_of,
    fresh_pg_database,
    seed_system,
    worker_process,
)

START, END = "<!-- bench:load:start -->", "<!-- bench:load:end -->"


def _model_payload(campaign_root: Path) -> dict:
    from server.campaigns import train_from_directory
    from tests.conftest import DESIGN_SEED, make_campaign

    design = make_campaign("design", DESIGN_SEED, campaign_root)
    model, _ = train_from_directory(design, seed=0, jobs=os.cpu_count() or 1)
    return json.loads(json.dumps(model.to_dict()))




def _pct(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, max(0, round(q * (len(ordered) - 1))))]


def run(args: argparse.Namespace) -> dict:
    campaign_root = Path(args.campaign_dir or tempfile.mkdtemp(prefix="hmsm-load-campaign-"))
    print("training the model (quick design campaign, cached in", campaign_root, ")")
    payload = _model_payload(campaign_root)
    tails = [f"LOAD{u + 1:02d}" for u in range(args.uploaders)]
    print(f"making {args.uploaders * args.flights} flight logs")
    bodies = {tail: [make_parquet(tail, f"F{n + 1:04d}", seed=n) for n in range(args.flights)]
              for tail in tails}
    with tempfile.TemporaryDirectory(prefix="hmsm-load-") as tmp, \
            fresh_pg_database(args.pg_url, prefix="hmsm_load") as db_url:
        settings = Settings(data_dir=Path(tmp) / "data", database_url=db_url)
        keys = seed_system(settings, payload)
        admin = {"Authorization": f"Bearer {keys['admin']}"}
        up = {"Authorization": f"Bearer {keys['uploader']}",
              "Content-Type": "application/vnd.apache.parquet"}
        with running_server(env_of(settings), timeout_s=60) as url:
            with httpx.Client(base_url=url, timeout=60) as http:
                for tail in tails:
                    r = http.post("/api/v1/aircraft", headers=admin, json={
                        "tail": tail, "base": "Turin", "actuators": serials_for(tail)})
                    r.raise_for_status()
            latencies: list[float] = []
            statuses: dict[int, int] = {}
            lock = threading.Lock()
            deadline = time.monotonic() + args.timeout

            def uploader(tail: str) -> None:
                with httpx.Client(base_url=url, timeout=120) as http:
                    for body in bodies[tail]:
                        if time.monotonic() > deadline:
                            return
                        t0 = time.perf_counter()
                        r = http.post("/api/v1/flights", headers=up, content=body)
                        dt_s = time.perf_counter() - t0
                        with lock:
                            latencies.append(dt_s)
                            statuses[r.status_code] = statuses.get(r.status_code, 0) + 1

            with worker_process(settings, "--concurrency", str(args.workers)):
                t_start = time.monotonic()
                with ThreadPoolExecutor(args.uploaders) as pool:
                    list(pool.map(uploader, tails))
                t_uploaded = time.monotonic()
                accepted = statuses.get(202, 0)
                engine = create_engine(settings.effective_database_url)
                analysed, first_done = 0, None
                while time.monotonic() < deadline:
                    with Session(engine) as s:
                        analysed = s.scalar(select(func.count()).select_from(Flight)
                                            .where(Flight.status == FlightStatus.ANALYZED)) or 0
                        pending = s.scalar(select(func.count()).select_from(Flight).where(
                            Flight.status.in_((FlightStatus.RECEIVED, FlightStatus.QUEUED,
                                              FlightStatus.ANALYZING)))) or 0
                    if analysed and first_done is None:
                        first_done = time.monotonic()
                    if pending == 0:
                        break
                    time.sleep(0.5)
                t_end = time.monotonic()
            with Session(engine) as s:
                n_flights = s.scalar(select(func.count()).select_from(Flight)) or 0
                n_jobs = s.scalar(select(func.count()).select_from(Job)) or 0
                n_done = s.scalar(select(func.count()).select_from(Job)
                                  .where(Job.status == JobStatus.DONE)) or 0
                n_records = s.scalar(select(func.count()).select_from(HealthRecord)) or 0
                distinct = s.scalar(select(func.count(func.distinct(
                    Flight.tail + ":" + Flight.flight_code)))) or 0
            engine.dispose()
    minutes = max(t_end - t_start, 1e-9) / 60
    result = {
        "uploaders": args.uploaders, "flights_per_uploader": args.flights,
        "workers": args.workers, "uploads": len(latencies), "statuses": statuses,
        "upload_p50_ms": 1000 * statistics.median(latencies),
        "upload_p95_ms": 1000 * _pct(latencies, 0.95),
        "upload_max_ms": 1000 * max(latencies),
        "upload_phase_s": t_uploaded - t_start, "total_s": t_end - t_start,
        "analysed": analysed, "per_min": analysed / minutes,
        "per_min_per_worker": analysed / minutes / args.workers,
        "flights_in_db": n_flights, "distinct_flights": distinct, "jobs": n_jobs,
        "jobs_done": n_done, "health_records": n_records,
        "lost": accepted - analysed, "duplicated": n_flights - distinct + (n_jobs - n_flights)
        + (n_records - 3 * n_flights),
        "bytes_per_flight": len(next(iter(bodies.values()))[0]),
    }
    return result


def write_block(result: dict, command: str) -> None:
    now = dt.datetime.now(dt.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    r = result
    block = f"""## Load test: uploads and analysis on PostgreSQL (API + {r['workers']} workers)

`{command}` -- {now}; {cpu_model()}, {os.cpu_count()} cores (shared with other jobs), Python
{platform.python_version()}, PostgreSQL on loopback (fresh database). {r['uploaders']} uploader
threads x {r['flights_per_uploader']} flights, each a distinct (aircraft, flight), factory-made
12 s logs of {r['bytes_per_flight'] / 1e6:.2f} MB (Parquet); analysis by `hmsm worker
--concurrency {r['workers']}` with the model trained on the quick design campaign.

| figure | value |
|---|---|
| uploads (HTTP status: count) | {r['uploads']} ({', '.join(f'{k}: {v}' for k, v in sorted(r['statuses'].items()))}) |
| upload latency p50 / p95 / max | {r['upload_p50_ms']:.0f} / {r['upload_p95_ms']:.0f} / {r['upload_max_ms']:.0f} ms |
| upload phase (all uploads sent) | {r['upload_phase_s']:.1f} s |
| flights analysed | {r['analysed']} in {r['total_s']:.1f} s from the first upload |
| analysis throughput | {r['per_min']:.1f} flights/min ({r['per_min_per_worker']:.1f} per worker) |
| lost / duplicated | {r['lost']} / {r['duplicated']} (flights {r['flights_in_db']}, distinct {r['distinct_flights']}, jobs {r['jobs']} done {r['jobs_done']}, health records {r['health_records']}) |

Throughput counts from the first upload to the last analysed flight, so uploads and analysis
overlap; both compete for the same {os.cpu_count()} cores as the uploaders themselves."""
    replace_block(START, END, block)
    print(f"wrote {BENCHMARKS}")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--uploaders", type=int, default=8)
    parser.add_argument("--flights", type=int, default=25, help="flights per uploader")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--timeout", type=float, default=900, help="hard stop [s]")
    parser.add_argument("--pg-url", default=os.environ.get(
        "HMSM_TEST_POSTGRES_URL", "postgresql://postgres@127.0.0.1:5432/postgres"),
        help="any database on the server; a fresh one is created next to it")
    parser.add_argument("--campaign-dir", default=os.environ.get("PHM_CAMPAIGN_DIR"),
                        help="cache of the quick design campaign")
    parser.add_argument("--no-write", action="store_true", help="do not touch BENCHMARKS.md")
    args = parser.parse_args()
    result = run(args)
    print(json.dumps(result, indent=2))
    if not args.no_write:
        write_block(result, "python bench/load_test.py " + " ".join(sys.argv[1:]))
    return 0 if result["lost"] == 0 and result["duplicated"] == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
