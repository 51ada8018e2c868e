"""GET /metrics on the app in-process, SQLite and PostgreSQL: who may read it, the route label
bounded whatever clients send, and the queue and the workers' telemetry read from the
database (a real ``Worker`` analysing real uploads). The same across processes, with
``hmsm serve`` and ``hmsm worker`` started as programs: tests/production/test_metrics_live.py.
"""

from __future__ import annotations

import threading
import time

from fastapi.testclient import TestClient
from pydantic import SecretStr

from server.app import create_app
from server.config import Settings
from server.jobs.worker import Worker
from tests.api.conftest import auth
from tests.flightlog_factory import make_parquet
from tests.scrape import STAGES, samples, value

PARQUET = {"Content-Type": "application/vnd.apache.parquet"}
TOKEN = "m" * 40


def scrape(client: TestClient, token: str = TOKEN) -> dict:  # type: ignore[type-arg]
    r = client.get("/metrics", headers=auth(token))
    assert r.status_code == 200, r.text
    assert r.headers["content-type"].startswith("text/plain")
    return samples(r.text)


def test_metrics_need_the_metrics_token_or_an_admin_key(settings: Settings) -> None:
    app = create_app(settings.model_copy(update={"metrics_token": SecretStr(TOKEN),
                                                 "auth_failures_per_minute": 0}))
    from server.auth import create_key
    from server.db import session_scope

    with session_scope(app.state.session_factory) as s:
        mine = {r: create_key(session=s, name=r, role=r)[1] for r in ("viewer", "admin")}
    with TestClient(app) as client:
        assert client.get("/metrics").status_code == 401
        assert client.get("/metrics", headers=auth("x" * 40)).status_code == 401
        assert client.get("/metrics", headers=auth(TOKEN[:-1])).status_code == 401
        r = client.get("/metrics", headers=auth(mine["viewer"]))
        assert r.status_code == 403 and r.json()["error"]["code"] == "forbidden"
        client.cookies.set("hmsm_session", mine["admin"])  # the cookie is not a scraper's
        assert client.get("/metrics").status_code == 401
        client.cookies.clear()
        assert client.get("/metrics", headers=auth(mine["admin"])).status_code == 200
        assert value(scrape(client), "hmsm_telemetry_up") == 1.0
    app.state.engine.dispose()


def test_without_a_metrics_token_only_admin_keys_read_metrics(client: TestClient,
                                                              keys: dict[str, str]) -> None:
    for role in ("viewer", "uploader", "operator", "maintainer"):
        assert client.get("/metrics", headers=auth(keys[role])).status_code == 403, role
    assert client.get("/metrics", headers=auth("m" * 40)).status_code == 401
    assert client.get("/metrics", headers=auth(keys["admin"])).status_code == 200


def test_wrong_metrics_tokens_spend_the_failed_authentication_budget(settings: Settings) -> None:
    app = create_app(settings.model_copy(update={"metrics_token": SecretStr(TOKEN),
                                                 "auth_failures_per_minute": 3}))
    with TestClient(app) as client:
        codes = [client.get("/metrics", headers=auth(f"guess-{i:036d}")).status_code
                 for i in range(5)]
        assert codes == [401, 401, 401, 429, 429]
        assert client.get("/metrics", headers=auth(TOKEN)).status_code == 200  # a right one is
        # never refused for the guesses (each a new key: only the address's budget is spent)
    app.state.engine.dispose()


def test_the_route_label_is_the_template_and_stays_bounded(client: TestClient,
                                                           keys: dict[str, str]) -> None:
    viewer = auth(keys["viewer"])
    for i in range(50):
        client.get(f"/api/v1/flights/{1000 + i}", headers=viewer)
        client.get(f"/no/such/path/{i}")
        client.request("BREW", f"/coffee/{i}")
    client.get("/static/app.js")
    text = client.get("/metrics", headers=auth(keys["admin"])).text
    scraped = samples(text)
    routes = {dict(k[1]).get("route") for k in scraped if k[0] == "hmsm_http_requests_total"}
    assert "/api/v1/flights/{flight_id}" in routes and "/static/{path}" in routes
    assert "<unmatched>" in routes
    assert not any(r and ("1000" in r or "no/such" in r or "coffee" in r) for r in routes)
    assert value(scraped, "hmsm_http_requests_total", method="GET",
                 route="/api/v1/flights/{flight_id}", status="404") == 50
    assert value(scraped, "hmsm_http_requests_total", method="OTHER", route="<unmatched>",
                 status="404") == 50
    assert value(scraped, "hmsm_http_request_duration_seconds_count", method="GET",
                 route="/api/v1/flights/{flight_id}") == 50


def test_queue_jobs_stages_and_heartbeats_come_from_the_database(
        app, client: TestClient, keys: dict[str, str], aircraft: str, active_model,  # type: ignore[no-untyped-def]
        settings: Settings) -> None:
    admin, up = auth(keys["admin"]), {**PARQUET, **auth(keys["uploader"])}
    sizes = []
    for n in range(3):
        data = make_parquet(aircraft, f"F{n + 1}", seed=n, duration_s=20)
        sizes.append(len(data))
        assert client.post("/api/v1/flights", content=data, headers=up).status_code == 202
    time.sleep(0.05)
    before = scrape(client, keys["admin"])
    assert value(before, "hmsm_queue_depth", kind="analyze_flight") == 3
    assert value(before, "hmsm_queue_depth", kind="train_model") == 0
    assert value(before, "hmsm_queue_oldest_age_seconds", kind="analyze_flight") >= 0.05
    assert value(before, "hmsm_upload_bytes_count", outcome="accepted") == 3
    assert value(before, "hmsm_upload_bytes_sum", outcome="accepted") == sum(sizes)

    # the third flight's file is gone from disk: its attempt fails and is retried later
    third = client.get("/api/v1/flights?limit=1", headers=admin).json()["items"][0]
    app.state.blobs.path_of(third["sha256"]).unlink()

    stop = threading.Event()
    worker = Worker(settings, lease_s=30, poll_s=0.1, beat_s=0.2)
    thread = threading.Thread(target=worker.run, args=(stop,), daemon=True)
    thread.start()
    try:
        deadline = time.monotonic() + 120
        while True:
            during = scrape(client, keys["admin"])
            retried = value(during, "hmsm_job_attempts_total", kind="analyze_flight",
                            outcome="retried")
            if retried == 1 and value(during, "hmsm_job_attempts_total", kind="analyze_flight",
                                      outcome="done") == 2:
                break
            assert time.monotonic() < deadline, "the worker did not finish two jobs"
            time.sleep(0.2)
        beat = value(during, "hmsm_worker_last_heartbeat_timestamp_seconds",
                     worker=worker.worker_id, host=worker.worker_id.split(":")[0])
        assert beat is not None and abs(time.time() - beat) < 10
    finally:
        stop.set()
        thread.join(timeout=60)
        worker.engine.dispose()

    after = scrape(client, keys["admin"])
    assert value(after, "hmsm_queue_depth", kind="analyze_flight") == 1  # the retry, backing off
    assert value(after, "hmsm_jobs", kind="analyze_flight", status="running") == 0
    assert value(after, "hmsm_job_duration_seconds_count", kind="analyze_flight") == 2
    for stage in STAGES:  # the factory's flights alarm at once: every stage ran
        count = value(after, "hmsm_job_stage_duration_seconds_count", kind="analyze_flight",
                      stage=stage)
        assert count and count > 0, stage
        assert value(after, "hmsm_job_stage_duration_seconds_sum", kind="analyze_flight",
                     stage=stage) > 0
    assert value(after, "hmsm_job_stage_duration_seconds_count", kind="analyze_flight",
                 stage="decode") == 2
    assert not any(k[0] == "hmsm_worker_last_heartbeat_timestamp_seconds" for k in after), \
        "a worker that stopped cleanly removes its heartbeat"


def test_metrics_token_settings_are_checked(tmp_path) -> None:  # type: ignore[no-untyped-def]
    import pytest
    from pydantic import ValidationError

    for bad in ("short", "x" * 31, "with space " * 4, "é" * 40):
        with pytest.raises(ValidationError):
            Settings(data_dir=tmp_path, metrics_token=bad)
    path = tmp_path / "token"
    path.write_text(TOKEN + "\n")  # a trailing newline, as `openssl rand -hex 32 > file` writes
    assert Settings(data_dir=tmp_path,
                    metrics_token_file=path).metrics_token.get_secret_value() == TOKEN
    with pytest.raises(ValidationError, match="not both"):
        Settings(data_dir=tmp_path, metrics_token=TOKEN, metrics_token_file=path)
    with pytest.raises(ValidationError, match="cannot read"):
        Settings(data_dir=tmp_path, metrics_token_file=tmp_path / "missing")
    assert TOKEN not in repr(Settings(data_dir=tmp_path, metrics_token=TOKEN))
