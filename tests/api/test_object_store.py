"""Flight logs in an S3-compatible object store (moto's server over HTTP), through the API and
the worker: an outage answers 503 and loses nothing (a flight whose log cannot be read waits
as queued), a store that takes connections and never answers costs an upload at most the
configured deadline and makes the service not ready, and an API process and a worker that
share only the database and the store (separate data directories) work together, raw-log
retention included. On SQLite and, when HMSM_TEST_POSTGRES_URL is set, PostgreSQL."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient
from sqlalchemy import select, update

from server.app import create_app
from server.auth import create_key
from server.config import Settings
from server.db import session_scope
from server.jobs.worker import Worker
from server.models import Flight, Job, utcnow
from server.services import models as model_service
from server.services import retention
from tests.api.conftest import auth
from tests.conftest import truncate_all
from tests.flightlog_factory import make_parquet, serials_for
from tests.s3_server import AWS_ENV, MotoS3, SilentServer

PARQUET = {"Content-Type": "application/vnd.apache.parquet"}


@pytest.fixture
def own_s3(monkeypatch: pytest.MonkeyPatch) -> Iterator[MotoS3]:
    """An S3 server of this test's own, which it may stop and start again."""
    for name, value in AWS_ENV.items():
        monkeypatch.setenv(name, value)
    server = MotoS3()
    server.start()
    yield server
    server.stop()


def _database_url(backend: str, tmp_path: Path, request: pytest.FixtureRequest) -> str:
    if backend == "postgres":
        url = request.getfixturevalue("pg_database")
        truncate_all(url)
        return url
    return f"sqlite:///{tmp_path / 'shared.sqlite3'}"


@pytest.fixture
def settings(backend: str, tmp_path: Path, request: pytest.FixtureRequest,
             own_s3: MotoS3) -> Settings:
    """The API's settings (tests/api/conftest.py builds the app from them): blobs in the
    object store, the database outside the data directory."""
    return Settings(data_dir=tmp_path / "api", blob_url=f"s3://{own_s3.new_bucket()}/flights",
                    s3_endpoint_url=own_s3.endpoint,
                    database_url=_database_url(backend, tmp_path, request))


def _upload(client: TestClient, key: str, tail: str, flight: str, seed: int = 0):  # type: ignore[no-untyped-def]
    return client.post("/api/v1/flights", content=make_parquet(tail, flight, seed=seed),
                       headers={**PARQUET, **auth(key)})


def _bucket(settings: Settings) -> str:
    return settings.blob_bucket[0]


def test_store_outage_answers_503_loses_nothing_and_recovers(
        app, client: TestClient, keys: dict[str, str], aircraft: str, settings: Settings,
        own_s3: MotoS3, active_model: None) -> None:  # type: ignore[no-untyped-def]
    first = _upload(client, keys["uploader"], aircraft, "F0001")
    assert first.status_code == 202, first.text
    first_id = first.json()["id"]

    own_s3.stop()
    down = _upload(client, keys["uploader"], aircraft, "F0002", seed=1)
    assert down.status_code == 503, down.text
    assert down.json()["error"]["code"] == "storage_unreachable"
    assert down.headers["Retry-After"] == "30"
    listing = client.get("/api/v1/flights", headers=auth(keys["viewer"])).json()
    assert [f["id"] for f in listing["items"]] == [first_id]  # no row without its blob
    assert list(settings.tmp_dir.iterdir()) == []  # nor a spooled file left behind
    signals = client.get(f"/api/v1/flights/{first_id}/signals?channels=WT.x",
                         headers=auth(keys["viewer"]))
    assert signals.status_code == 503 and signals.json()["error"]["code"] == "storage_unreachable"
    # the worker cannot read the log: the job waits (deferred), no attempt is spent on it
    worker = Worker(settings.model_copy(update={"data_dir": settings.data_dir.parent / "w"}))
    try:
        assert worker.run_once()
    finally:
        worker.engine.dispose()
    with session_scope(app.state.session_factory) as s:
        job = s.scalar(select(Job).where(Job.flight_id == first_id))
        assert (job.status, job.attempts) == ("queued", 0), (job.status, job.attempts)
        assert "does not answer" in (job.last_error or "")
    # and the flight says so: queued as its job, with the cause, not "analyzing"
    waiting = client.get(f"/api/v1/flights/{first_id}", headers=auth(keys["viewer"])).json()
    assert waiting["status"] == "queued", waiting
    assert [r["code"] for r in waiting["reasons"]] == ["storage_unreachable"], waiting

    own_s3.start()
    again = _upload(client, keys["uploader"], aircraft, "F0002", seed=1)
    assert again.status_code == 202, again.text
    back = client.get(f"/api/v1/flights/{first_id}/signals?channels=WT.x",
                      headers=auth(keys["viewer"]))
    assert back.status_code == 200 and back.json()["channels"]["WT.x"]
    assert len(own_s3.keys(_bucket(settings))) == 2
    # its deferral over, the job runs: analysed, the waiting reason gone
    with session_scope(app.state.session_factory) as s:
        s.execute(update(Job).where(Job.flight_id == first_id).values(run_after=utcnow()))
    worker = Worker(settings.model_copy(update={"data_dir": settings.data_dir.parent / "w"}))
    try:
        assert worker.run_once()
    finally:
        worker.engine.dispose()
    done = client.get(f"/api/v1/flights/{first_id}", headers=auth(keys["viewer"])).json()
    assert (done["status"], done["reasons"]) == ("analyzed", []), done


REQUEST_OWN_WORK_S = 0.5


def test_a_store_that_never_answers_costs_an_upload_at_most_the_deadline(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A store that takes connections and never answers: the upload is 503 with Retry-After
    within HMSM_BLOB_STORE_DEADLINE_S and the request's own work (one retry made, the next
    refused by the deadline),
    and /health/ready says the store does not answer, naming it, within the probe's timeout.
    Bounded here as a client would: without the deadline the upload took 150 s."""
    for name, value in AWS_ENV.items():
        monkeypatch.setenv(name, value)
    silent = SilentServer()
    settings = Settings(data_dir=tmp_path / "api", blob_url="s3://hmsm-silent/flights",
                        s3_endpoint_url=silent.endpoint,
                        database_url=f"sqlite:///{tmp_path / 'db.sqlite3'}",
                        blob_store_connect_timeout_s=0.5, blob_store_read_timeout_s=1.0,
                        blob_store_deadline_s=4.0, blob_store_probe_timeout_s=0.5)
    seen: dict[str, Any] = {}

    def scenario() -> None:
        try:
            app = create_app(settings)
            with TestClient(app, raise_server_exceptions=False) as client:
                with session_scope(app.state.session_factory) as s:
                    key = create_key(session=s, name="t-admin", role="admin")[1]
                r = client.post("/api/v1/aircraft", headers=auth(key), json={
                    "tail": "T001", "base": "Turin", "actuators": serials_for("T001")})
                assert r.status_code == 201, r.text
                before = silent.accepted
                start = time.monotonic()
                seen["upload"] = _upload(client, key, "T001", "F0001")
                seen["upload_s"] = time.monotonic() - start
                seen["tries"] = silent.accepted - before
                start = time.monotonic()
                seen["ready"] = client.get("/api/v1/health/ready")
                seen["ready_s"] = time.monotonic() - start
            app.state.engine.dispose()
        except BaseException as exc:  # reported by the test's thread
            seen["error"] = exc

    runner = threading.Thread(target=scenario, daemon=True)
    runner.start()
    runner.join(timeout=30)
    silent.close()  # unblocks a client still waiting on it
    assert not runner.is_alive(), f"still waiting on the store after 30 s: {seen}"
    if "error" in seen:
        raise seen["error"]

    up = seen["upload"]
    assert up.status_code == 503, up.text
    assert up.json()["error"]["code"] == "storage_unreachable"
    assert int(up.headers["Retry-After"]) > 0
    # the deadline bounds the store's operation; the request's own work (auth, spooling the
    # body, its rows) comes on top, and a socket's timeout fires a few ms late (4.006 s seen)
    assert seen["upload_s"] <= settings.blob_store_deadline_s + REQUEST_OWN_WORK_S, seen
    assert seen["tries"] == 2, seen  # the HEAD tried again once; a third could not end in time

    ready = seen["ready"]
    assert ready.status_code == 503, ready.text
    error = ready.json()["error"]
    assert error["code"] == "storage_unreachable", error
    assert "s3://hmsm-silent/flights" in error["message"], error
    assert error["details"]["blob_store"] == "s3://hmsm-silent/flights", error
    assert seen["ready_s"] <= 2 * settings.blob_store_probe_timeout_s + 0.5, seen


def test_a_blob_whose_delete_failed_is_swept_once_old(
        app, client: TestClient, keys: dict[str, str], aircraft: str, settings: Settings,
        own_s3: MotoS3) -> None:  # type: ignore[no-untyped-def]
    """A rejected flight deleted while the store is away: the row goes (204), its object
    stays; the orphan sweep removes it once older than its age limit, and nothing a row
    keeps."""
    kept = _upload(client, keys["uploader"], aircraft, "F0001")
    assert kept.status_code == 202, kept.text
    stray = _upload(client, keys["uploader"], "NOSUCH", "F0001", seed=3)  # unknown aircraft
    assert stray.status_code == 422, stray.text
    bucket = _bucket(settings)
    assert len(own_s3.keys(bucket)) == 2

    own_s3.stop()
    gone = client.delete(f"/api/v1/flights/{stray.json()['error']['details']['id']}",
                         headers=auth(keys["admin"]))
    assert gone.status_code == 204, gone.text
    own_s3.start()
    assert len(own_s3.keys(bucket)) == 2  # the orphan

    with session_scope(app.state.session_factory) as s:
        assert retention.sweep_orphans(session=s, blobs=app.state.blobs) == 0  # young: kept
        assert retention.sweep_orphans(session=s, blobs=app.state.blobs, min_age_s=0) == 1
    with session_scope(app.state.session_factory) as s:
        row = s.get(Flight, kept.json()["id"])
        assert own_s3.keys(bucket) == [f"flights/{row.blob_path}"]


@pytest.fixture
def api_and_worker(backend: str, tmp_path: Path, request: pytest.FixtureRequest,
                   s3_server: MotoS3, shipped_model):  # type: ignore[no-untyped-def]
    """An API app and a worker with data directories of their own, sharing only the database
    and the bucket; the worker keeps the raw logs of 1 analysed flight per aircraft."""
    shared = {"database_url": _database_url(backend, tmp_path, request),
              "blob_url": f"s3://{s3_server.new_bucket()}/flights",
              "s3_endpoint_url": s3_server.endpoint}
    app = create_app(Settings(data_dir=tmp_path / "api", **shared))
    worker = Worker(Settings(data_dir=tmp_path / "worker", raw_retention_flights=1, **shared))
    with session_scope(app.state.session_factory) as s:
        model_service.store_trained(session=s, name="t", payload=shipped_model[0],
                                    report=shipped_model[1], make_active=True)
        keys = {r: create_key(session=s, name=f"t-{r}", role=r)[1]
                for r in ("admin", "uploader", "viewer")}
    with TestClient(app, raise_server_exceptions=False) as client:
        yield app, client, worker, keys
    worker.engine.dispose()
    app.state.engine.dispose()


def test_api_and_worker_share_only_the_database_and_the_object_store(
        api_and_worker, s3_server: MotoS3, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    app, client, worker, keys = api_and_worker
    r = client.post("/api/v1/aircraft", headers=auth(keys["admin"]),
                    json={"tail": "T001", "base": "Turin", "actuators": serials_for("T001")})
    assert r.status_code == 201, r.text
    ids = []
    for i in range(3):
        up = _upload(client, keys["uploader"], "T001", f"F{i:04d}", seed=i)
        assert up.status_code == 202, up.text
        ids.append(up.json()["id"])
    while worker.run_once():  # one analysis job per flight, in upload order
        pass

    bucket = _bucket(app.state.settings)
    with session_scope(app.state.session_factory) as s:
        rows = {f.id: f for f in s.scalars(select(Flight).where(Flight.id.in_(ids)))}
        assert {f.status for f in rows.values()} == {"analyzed"}
        kept = {f.id for f in rows.values() if f.raw_pruned_at is None}
        expected = {f"flights/{f.blob_path}" for f in rows.values() if f.id in kept}
    # retention acted on the object store: only the flights keeping their log have an object
    assert ids[-1] in kept and len(kept) < len(ids)
    assert s3_server.keys(bucket) == sorted(expected)
    for flight_id in ids:
        sig = client.get(f"/api/v1/flights/{flight_id}/signals?channels=WT.x&max_points=50",
                         headers=auth(keys["viewer"]))
        if flight_id in kept:  # read back by the API from the bytes the worker analysed
            assert sig.status_code == 200 and len(sig.json()["channels"]["WT.x"]) <= 50
        else:
            assert sig.status_code == 410 and sig.json()["error"]["code"] == "raw_pruned"
    # neither process wrote a blob to its own disk
    assert not (tmp_path / "api" / "blobs").exists()
    assert not (tmp_path / "worker" / "blobs").exists()
    storage = client.get("/api/v1/storage", headers=auth(keys["admin"])).json()["blob_store"]
    assert (storage["referenced_files"], storage["unreferenced_files"],
            storage["missing_files"]) == (len(kept), 0, 0)
