"""Upload-to-alarm latency of the running system (API + one worker, embedded SQLite).

For each of N simulated aircraft: one healthy flight is uploaded and analysed, then a flight
with a MOSFET base-drive open circuit (BDO, alarmed on its first faulty flight); the latency is
the time from sending that upload to the alarm being listed by the API. The model is trained on
a design campaign (``--design``, default: simulate a quick one with seed 1).

    python bench/alarm_latency.py [--design DIR] [--aircraft 3]

Figures go to docs/BENCHMARKS.md between ``<!-- bench:latency:start -->`` and
``<!-- bench:latency:end -->``.
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import platform
import socket
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import httpx
import numpy as np
from _report import cpu_model, replace_block

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from server.auth import create_key  # noqa: E402
from server.campaigns import train_from_directory  # noqa: E402
from server.config import Settings  # noqa: E402
from server.db import make_engine, make_session_factory, session_scope  # noqa: E402
from server.flightlog import write_parquet  # noqa: E402
from server.migrate import upgrade  # noqa: E402
from server.services import models as model_service  # noqa: E402
from sim_worker import build_aircraft, healthy, new_fault, simulate_flight  # noqa: E402

START, END = "<!-- bench:latency:start -->", "<!-- bench:latency:end -->"


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _wait(predicate, timeout_s: float) -> float:  # type: ignore[no-untyped-def]
    t0 = time.perf_counter()
    while not predicate():
        if time.perf_counter() - t0 > timeout_s:
            raise TimeoutError
        time.sleep(0.05)
    return time.perf_counter()


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--design", help="design campaign directory (default: simulate one)")
    ap.add_argument("--aircraft", type=int, default=3)
    args = ap.parse_args()
    work = Path(tempfile.mkdtemp(prefix="hmsm-latency-"))
    design = Path(args.design) if args.design else work / "design"
    if not (design / "manifest.json").exists():
        from sim_worker import run_campaign

        run_campaign("design", design, seed=1, scale="quick", progress=True)
    model, report = train_from_directory(design, seed=0, jobs=os.cpu_count() or 1)
    settings = Settings(data_dir=work / "data")
    settings.data_dir.mkdir(parents=True)
    upgrade(settings.effective_database_url)
    engine = make_engine(settings.effective_database_url)
    with session_scope(make_session_factory(engine)) as s:
        model_service.store_trained(session=s, name="latency", report=report, make_active=True,
                                    payload=json.loads(json.dumps(model.to_dict())))
        key = create_key(session=s, name="bench", role="admin")[1]
    engine.dispose()
    env = {**os.environ, "HMSM_DATA_DIR": str(settings.data_dir)}
    port = _free_port()
    url = f"http://127.0.0.1:{port}/api/v1"
    procs = [subprocess.Popen([sys.executable, "-m", "server.cli", "serve", "--port", str(port),
                               "--log-level", "warning"], env=env, cwd=ROOT),
             subprocess.Popen([sys.executable, "-m", "server.cli", "worker"], env=env, cwd=ROOT,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
    h = {"Authorization": f"Bearer {key}"}
    latencies, analysis = [], []
    try:
        def up() -> bool:
            try:
                return httpx.get(url + "/health/ready").status_code == 200
            except httpx.TransportError:
                return False

        _wait(up, 60)
        for i in range(args.aircraft):
            ac = build_aircraft(f"LAT{i:02d}", ("Turin", "Vancouver", "Abu Dhabi")[i % 3], 100 + i)
            assert httpx.post(url + "/aircraft", headers=h, json={
                "tail": ac.tail, "base": ac.base, "actuators": ac.serials}).status_code == 201
            bdo = new_fault("BDO", "WT", np.random.default_rng(i))
            for n, fault in ((1, healthy()), (2, bdo)):
                log, _ = simulate_flight(ac, fault, n, np.random.default_rng([i, n]),
                                         duration_s=60.0)
                data = write_parquet(log)
                t0 = time.perf_counter()
                r = httpx.post(url + "/flights", content=data, headers={
                    **h, "Content-Type": "application/vnd.apache.parquet"}, timeout=60)
                assert r.status_code == 202, r.text
                fid = r.json()["id"]
                t_done = _wait(lambda fid=fid: httpx.get(f"{url}/flights/{fid}", headers=h)
                               .json()["status"] == "analyzed", 120)
                analysis.append(t_done - t0)
                if n == 2:
                    t_alarm = _wait(lambda t=ac.tail: httpx.get(
                        f"{url}/alarms?aircraft={t}", headers=h).json()["total"] > 0, 60)
                    latencies.append(t_alarm - t0)
    finally:
        for p in procs:
            p.terminate()
            p.wait(timeout=30)
    now = dt.datetime.now(dt.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    lat = (f"mean {statistics.mean(latencies):.2f} s, max {max(latencies):.2f} s "
           f"({len(latencies)} alarms)")
    ana = (f"mean {statistics.mean(analysis):.2f} s, max {max(analysis):.2f} s "
           f"({len(analysis)} flights)")
    per_min = 60 / statistics.mean(analysis)
    text = f"""## Upload-to-alarm latency (API + 1 worker, SQLite), `bench/alarm_latency.py`

`python bench/alarm_latency.py` -- {now}; {cpu_model()}, {os.cpu_count()} cores, Python
{platform.python_version()}. {args.aircraft} aircraft; per aircraft a healthy 60 s flight, then
one with a BDO fault on the wingtip drive (alarmed on its first faulty flight).

| figure | value |
|---|---|
| upload sent -> alarm listed by the API | {lat} |
| upload sent -> flight analysed | {ana} |
| flights analysed per minute by one worker (from the mean above, serial) | {per_min:.0f} |

The worker polls the queue every 0.5 s when idle, which is part of the latency."""
    replace_block(START, END, text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
