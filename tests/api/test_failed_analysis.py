"""A flight whose analysis is given up ends ``failed`` with the reason, never ``analyzing`` for
good: listed as failed, shown on the dashboard, and queued again by an admin
(``POST /flights/{id}/retry``); between failed attempts it says ``queued`` with the failure.
Through the real worker (``server.jobs.worker.Worker``) on each backend."""

from __future__ import annotations

import time

from fastapi.testclient import TestClient
from sqlalchemy import update

from server.config import Settings
from server.jobs import queue
from server.jobs.worker import Worker
from server.models import Job, utcnow
from tests.api.conftest import auth
from tests.flightlog_factory import make_parquet
from tests.signin import sign_in

PARQUET = {"Content-Type": "application/vnd.apache.parquet"}


def _upload(client: TestClient, keys: dict[str, str], tail: str, flight: str) -> int:
    r = client.post("/api/v1/flights", content=make_parquet(tail, flight),
                    headers={**PARQUET, **auth(keys["uploader"])})
    assert r.status_code == 202, r.text
    return int(r.json()["id"])


def _job_of(client: TestClient, keys: dict[str, str], flight_id: int) -> dict:  # type: ignore[type-arg]
    jobs = client.get(f"/api/v1/jobs?flight_id={flight_id}", headers=auth(keys["viewer"])).json()
    assert jobs["total"] == 1
    return jobs["items"][0]  # type: ignore[no-any-return]


def _flight(client: TestClient, keys: dict[str, str], flight_id: int) -> dict:  # type: ignore[type-arg]
    return client.get(f"/api/v1/flights/{flight_id}",  # type: ignore[no-any-return]
                      headers=auth(keys["viewer"])).json()


def _claimed_by_workers_that_die(app, times: int) -> None:  # type: ignore[no-untyped-def]
    """``times`` claims never finished: what workers killed mid-job (say, out of memory) leave
    behind, each lease running out before the next claim."""
    for i in range(times):
        job = queue.claim_next(app.state.session_factory, worker_id=f"killed-{i}", lease_s=0.05)
        assert job is not None and job.attempts == i + 1
        time.sleep(0.1)


def test_analysis_abandoned_on_its_last_attempt_fails_and_an_admin_retries_it(
        app, client: TestClient, keys: dict[str, str], aircraft: str, settings: Settings
        ) -> None:
    flight_id = _upload(client, keys, aircraft, "F1")
    other_id = _upload(client, keys, aircraft, "F2")
    _claimed_by_workers_that_die(app, times=_job_of(client, keys, flight_id)["max_attempts"])

    worker = Worker(settings)
    try:
        worker.run_once()  # buries the abandoned job; the next flight's job defers (no model)
    finally:
        worker.engine.dispose()
    failed = _flight(client, keys, flight_id)
    assert failed["status"] == "failed"
    [reason] = failed["reasons"]
    assert reason["code"] == "analysis_failed" and reason["details"]["attempts"] == 5
    assert reason["details"]["error"] == queue.ABANDONED
    assert _job_of(client, keys, flight_id)["status"] == "dead"
    listed = client.get("/api/v1/flights?status=failed", headers=auth(keys["viewer"])).json()
    assert [f["id"] for f in listed["items"]] == [flight_id]

    assert sign_in(client, keys["viewer"]).status_code == 303
    page = client.get("/fleet").text
    assert 'id="failed-flights"' in page and queue.ABANDONED.split(";")[0] in page

    retry = f"/api/v1/flights/{flight_id}/retry"
    for role in ("viewer", "uploader", "operator"):
        assert client.post(retry, headers=auth(keys[role])).status_code == 403
    refused = client.post(f"/api/v1/flights/{other_id}/retry", headers=auth(keys["admin"]))
    assert refused.status_code == 409 and refused.json()["error"]["code"] == "not_failed"
    assert client.post("/api/v1/flights/999999/retry",
                       headers=auth(keys["admin"])).status_code == 404
    again = client.post(retry, headers=auth(keys["admin"]))
    assert again.status_code == 202, again.text
    assert again.json()["status"] == "queued" and again.json()["reasons"] == []
    job = _job_of(client, keys, flight_id)
    assert job["status"] == "queued" and job["attempts"] == 0 and job["last_error"] is None
    assert client.post(retry, headers=auth(keys["admin"])).status_code == 409  # queued now


def test_analysis_failing_on_every_attempt_fails_then_analyses_once_retried(
        app, client: TestClient, keys: dict[str, str], aircraft: str, settings: Settings,
        active_model: None) -> None:  # type: ignore[no-untyped-def]
    flight_id = _upload(client, keys, aircraft, "F1")

    # a worker whose decode limits are below this flight's size fails it on every attempt
    narrow = Worker(settings.model_copy(update={"max_decoded_bytes": 1024}))
    try:
        for attempt in range(1, 6):
            with app.state.session_factory() as session:  # the backoff has passed
                session.execute(update(Job).values(run_after=utcnow()))
                session.commit()
            assert narrow.run_once()
            if attempt < 5:  # queued again: the flight waits, with why, not "analyzing"
                waiting = _flight(client, keys, flight_id)
                assert waiting["status"] == "queued", waiting
                [reason] = waiting["reasons"]
                assert reason["code"] == "analysis_retried"
                assert reason["message"].startswith(f"Attempt {attempt} of 5 failed (")
                assert "max_decoded_bytes" in reason["message"]
    finally:
        narrow.engine.dispose()
    failed = _flight(client, keys, flight_id)
    assert failed["status"] == "failed", failed
    error = failed["reasons"][0]["details"]["error"]
    assert error.startswith("server.flightlog.FlightLogError") and "max_decoded_bytes" in error
    assert _job_of(client, keys, flight_id)["status"] == "dead"

    assert client.post(f"/api/v1/flights/{flight_id}/retry",
                       headers=auth(keys["admin"])).status_code == 202
    worker = Worker(settings)
    try:
        assert worker.run_once()
    finally:
        worker.engine.dispose()
    assert _flight(client, keys, flight_id)["status"] == "analyzed"
    assert _job_of(client, keys, flight_id)["status"] == "done"
