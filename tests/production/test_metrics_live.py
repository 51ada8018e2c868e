"""/metrics across processes: ``hmsm serve`` and ``hmsm worker`` started as programs (SQLite and
PostgreSQL), flights uploaded through the API and analysed by the worker; what the worker
measured (every stage of the analysis, its heartbeat) reaches the API's /metrics through the
database alone, as it would from another host. The scraper's token comes from a file, as the
compose secret gives it; scrapes without it are refused."""

from __future__ import annotations

import time

import httpx
import pytest

from server.config import Settings
from tests.flightlog_factory import make_parquet, serials_for
from tests.live_server import running_server
from tests.production.helpers import env_of, seed_system, wait_until, worker_process
from tests.scrape import STAGES, samples, value

pytestmark = pytest.mark.slow

TOKEN = "0123456789abcdef" * 4
KIND = "analyze_flight"


def _scrape(http: httpx.Client) -> dict:  # type: ignore[type-arg]
    r = http.get("/metrics", headers={"Authorization": f"Bearer {TOKEN}"})
    assert r.status_code == 200, r.text
    return samples(r.text)


def test_a_live_analysis_shows_its_stages_queue_and_heartbeat_in_metrics(
        settings: Settings, shipped_model, tmp_path) -> None:  # type: ignore[no-untyped-def]
    keys = seed_system(settings, shipped_model[0])
    token_file = tmp_path / "metrics_token"
    token_file.write_text(TOKEN + "\n")
    env = {**env_of(settings), "HMSM_METRICS_TOKEN_FILE": str(token_file)}
    admin = {"Authorization": f"Bearer {keys['admin']}"}
    up = {"Authorization": f"Bearer {keys['uploader']}",
          "Content-Type": "application/vnd.apache.parquet"}
    with running_server(env) as url, httpx.Client(base_url=url, timeout=60) as http:
        # refused: no credentials, a reader's key, a wrong token
        assert http.get("/metrics").status_code == 401
        assert http.get("/metrics", headers={
            "Authorization": f"Bearer {keys['viewer']}"}).status_code == 403
        assert http.get("/metrics", headers={
            "Authorization": f"Bearer {TOKEN[::-1]}"}).status_code == 401

        assert http.post("/api/v1/aircraft", headers=admin, json={
            "tail": "MET1", "base": "Turin", "actuators": serials_for("MET1")}).status_code == 201
        sizes = []
        for n in range(4):
            data = make_parquet("MET1", f"F{n + 1}", seed=n, duration_s=20)
            sizes.append(len(data))
            assert http.post("/api/v1/flights", content=data, headers=up).status_code == 202
        queued = _scrape(http)  # no worker yet: the queue holds them all
        assert value(queued, "hmsm_queue_depth", kind=KIND) == 4
        assert value(queued, "hmsm_queue_oldest_age_seconds", kind=KIND) > 0
        assert value(queued, "hmsm_upload_bytes_sum", outcome="accepted") == sum(sizes)
        assert not any(k[0] == "hmsm_worker_last_heartbeat_timestamp_seconds" for k in queued)

        with worker_process(settings):
            def analysed() -> bool:
                page = http.get("/api/v1/flights?status=analyzed&limit=1", headers=admin)
                return page.json()["total"] == 4

            def attempts_recorded() -> bool:
                # the worker records an attempt in a transaction of its own, just after the
                # job's: a scrape may fall between the two
                return value(_scrape(http), "hmsm_job_attempts_total", kind=KIND,
                             outcome="done") == 4

            wait_until(analysed, 240, "the four flights analysed", every_s=0.5)
            wait_until(attempts_recorded, 30, "the four attempts recorded", every_s=0.2)
            live = _scrape(http)
            beats = {dict(labels)["worker"]: v for (name, labels), v in live.items()
                     if name == "hmsm_worker_last_heartbeat_timestamp_seconds"}
            assert len(beats) == 1, beats
            assert abs(time.time() - next(iter(beats.values()))) < 30
            costs = []
            for _ in range(20):
                start = time.perf_counter()
                _scrape(http)
                costs.append(time.perf_counter() - start)

        assert value(live, "hmsm_queue_depth", kind=KIND) == 0
        assert value(live, "hmsm_queue_oldest_age_seconds", kind=KIND) == 0
        assert value(live, "hmsm_job_attempts_total", kind=KIND, outcome="done") == 4
        assert value(live, "hmsm_job_duration_seconds_count", kind=KIND) == 4
        for stage in STAGES:
            count = value(live, "hmsm_job_stage_duration_seconds_count", kind=KIND, stage=stage)
            assert count is not None and count > 0, (stage, count)
            assert value(live, "hmsm_job_stage_duration_seconds_sum", kind=KIND,
                         stage=stage) > 0, stage
        for stage in ("decode", "features", "detection"):  # every flight, alarm or not
            assert value(live, "hmsm_job_stage_duration_seconds_count", kind=KIND,
                         stage=stage) == 4
        assert value(live, "hmsm_http_request_duration_seconds_count", method="POST",
                     route="/api/v1/flights") == 4
        assert value(live, "hmsm_telemetry_up") == 1

        stopped = _scrape(http)  # the worker stopped cleanly: its heartbeat is gone
        assert not any(k[0] == "hmsm_worker_last_heartbeat_timestamp_seconds" for k in stopped)
        read = value(stopped, "hmsm_telemetry_read_seconds")
    costs.sort()
    print(f"\nscrape: median {costs[10] * 1000:.1f} ms, max {costs[-1] * 1000:.1f} ms "
          f"(20 scrapes, the database part {read * 1000:.1f} ms); stage sums [s]: " + ", ".join(
              f"{s} {value(live, 'hmsm_job_stage_duration_seconds_sum', kind=KIND, stage=s):.3f}"
              for s in STAGES))
