"""Fault behaviour of the service: database outage, blob store failure, corrupted blob.

A worker killed mid-job (SIGKILL) is covered by
``tests/e2e/test_end_to_end.py::test_worker_killed_mid_job_loses_and_duplicates_nothing``
and is not repeated here.

The database outage never touches the shared PostgreSQL server: the API is started against a
loopback TCP proxy (``TcpProxy``) that the test cuts and restores.
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Iterator

import httpx
import pytest
from fastapi.testclient import TestClient
from sqlalchemy import create_engine, func, select
from sqlalchemy.orm import Session

from server.app import create_app
from server.config import Settings
from server.jobs.worker import Worker
from server.models import Flight, Job
from tests.flightlog_factory import make_parquet, serials_for
from tests.live_server import running_server
from tests.production.helpers import (
    TcpProxy,
    env_of,
    fresh_pg_database,
    seed_system,
    wait_until,
)

PG_URL = os.environ.get("HMSM_TEST_POSTGRES_URL")
PARQUET = {"Content-Type": "application/vnd.apache.parquet"}


def _auth(key: str, **extra: str) -> dict[str, str]:
    return {"Authorization": f"Bearer {key}", **extra}


def _aircraft(tail: str) -> dict[str, object]:
    return {"tail": tail, "base": "Turin", "actuators": serials_for(tail)}


def _assert_error_shape(response: httpx.Response, status: int, code: str) -> None:
    assert response.status_code == status, response.text
    body = response.json()
    assert set(body) == {"error"} and set(body["error"]) == {"code", "message", "details"}
    assert body["error"]["code"] == code, body


def _counts(url: str) -> tuple[int, int]:
    engine = create_engine(url)
    try:
        with Session(engine) as s:
            return (s.scalar(select(func.count()).select_from(Flight)) or 0,
                    s.scalar(select(func.count()).select_from(Job)) or 0)
    finally:
        engine.dispose()


def _register_and_upload(client: TestClient, keys: dict[str, str], tail: str) -> str:
    """Register ``tail`` and upload its flight F1; returns the flight's URL."""
    assert client.post("/api/v1/aircraft", json=_aircraft(tail),
                       headers=_auth(keys["admin"])).status_code == 201
    r = client.post("/api/v1/flights", content=make_parquet(tail, "F1"),
                    headers=_auth(keys["uploader"], **PARQUET))
    assert r.status_code == 202, r.text
    return r.headers["location"]


def _run_worker_once(settings: Settings) -> None:
    worker = Worker(settings, lease_s=30)
    try:
        assert worker.run_once()
    finally:
        worker.engine.dispose()


# --------------------------------------------------------------------------- database outage

@pytest.mark.postgres
@pytest.mark.skipif(not PG_URL, reason="HMSM_TEST_POSTGRES_URL not set")
def test_database_outage_answers_503_and_recovers_without_half_written_rows(tmp_path) -> None:
    assert PG_URL
    with fresh_pg_database(PG_URL) as direct_url:
        keys = seed_system(Settings(data_dir=tmp_path / "data", database_url=direct_url))
        host, port = "127.0.0.1", int(direct_url.split("://", 1)[1].split("@")[-1]
                                      .split("/")[0].rpartition(":")[2] or 5432)
        proxy = TcpProxy((host, port))
        proxied = Settings(data_dir=tmp_path / "data", database_url=proxy.url_for(direct_url))
        direct = Settings(data_dir=tmp_path / "data", database_url=direct_url)
        try:
            with running_server(env_of(proxied)) as url, httpx.Client(base_url=url,
                                                                     timeout=30) as http:
                assert http.post("/api/v1/aircraft", json=_aircraft("OUT1"),
                                 headers=_auth(keys["admin"])).status_code == 201
                first = make_parquet("OUT1", "F1")
                assert http.post("/api/v1/flights", content=first,
                                 headers=_auth(keys["uploader"], **PARQUET)).status_code == 202

                proxy.cut()
                second = make_parquet("OUT1", "F2", seed=2)
                for _ in range(3):  # the pool's stale connections, then fresh refusals
                    r = http.post("/api/v1/flights", content=second,
                                  headers=_auth(keys["uploader"], **PARQUET))
                    _assert_error_shape(r, 503, "database_unavailable")
                    assert r.headers.get("retry-after")
                _assert_error_shape(http.get("/api/v1/health/ready"), 503,
                                    "database_unavailable")
                assert http.get("/api/v1/health/live").status_code == 200
                assert _counts(direct.effective_database_url) == (1, 1)

                proxy.restore()
                wait_until(lambda: http.get("/api/v1/health/ready").status_code == 200, 30,
                           "readiness after the outage")
                r = http.post("/api/v1/flights", content=second,
                              headers=_auth(keys["uploader"], **PARQUET))
                assert r.status_code == 202, r.text  # not 200: nothing of it was kept before
                assert r.json()["duplicate"] is False
                assert _counts(direct.effective_database_url) == (2, 2)
        finally:
            proxy.close()


# ------------------------------------------------------------------------- blob store failure

@pytest.fixture
def local_api(tmp_path) -> Iterator[tuple[TestClient, Settings, dict[str, str]]]:
    """The app in-process on SQLite with keys and one aircraft ``BLOB1``."""
    settings = Settings(data_dir=tmp_path / "data")
    keys = seed_system(settings)
    with TestClient(create_app(settings)) as client:
        assert client.post("/api/v1/aircraft", json=_aircraft("BLOB1"),
                           headers=_auth(keys["admin"])).status_code == 201
        yield client, settings, keys


def _blocks(path) -> None:  # type: ignore[no-untyped-def]
    """Put a regular file where a directory must be: fails for root too (unlike chmod)."""
    if path.is_dir():
        shutil.rmtree(path)
    path.write_bytes(b"not a directory")


def test_blob_dir_unusable_answers_507_and_registers_nothing(local_api) -> None:  # type: ignore[no-untyped-def]
    client, settings, keys = local_api
    body = make_parquet("BLOB1", "F1")
    _blocks(settings.blob_dir)
    r = client.post("/api/v1/flights", content=body, headers=_auth(keys["uploader"], **PARQUET))
    _assert_error_shape(r, 507, "storage_unavailable")
    assert _counts(settings.effective_database_url) == (0, 0)

    settings.blob_dir.unlink()
    r = client.post("/api/v1/flights", content=body, headers=_auth(keys["uploader"], **PARQUET))
    assert r.status_code == 202, r.text


def test_blob_commit_failure_answers_507_and_leaves_no_flight_without_bytes(local_api) -> None:  # type: ignore[no-untyped-def]
    """The store fails at the rename into place (after decoding and checks)."""
    import hashlib

    client, settings, keys = local_api
    body = make_parquet("BLOB1", "F2", seed=3)
    shard = settings.blob_dir / hashlib.sha256(body).hexdigest()[:2]
    _blocks(shard)
    r = client.post("/api/v1/flights", content=body, headers=_auth(keys["uploader"], **PARQUET))
    _assert_error_shape(r, 507, "storage_unavailable")
    assert _counts(settings.effective_database_url) == (0, 0)
    assert list(settings.tmp_dir.iterdir()) == []  # the spooled upload was cleaned up

    shard.unlink()
    r = client.post("/api/v1/flights", content=body, headers=_auth(keys["uploader"], **PARQUET))
    assert r.status_code == 202, r.text
    flight = client.get(r.headers["location"], headers=_auth(keys["viewer"])).json()
    assert (settings.blob_dir / shard.name).is_dir()
    stored = settings.blob_dir / shard.name / flight["sha256"][2:4] / flight["sha256"]
    assert stored.read_bytes() == body


# ---------------------------------------------------------------------------- corrupted blob

def test_corrupted_blob_is_rejected_as_blob_corrupt_at_analysis(tmp_path, shipped_model) -> None:  # type: ignore[no-untyped-def]
    settings = Settings(data_dir=tmp_path / "data")
    keys = seed_system(settings, shipped_model[0])
    with TestClient(create_app(settings)) as client:
        location = _register_and_upload(client, keys, "CORR1")
        flight = client.get(location, headers=_auth(keys["viewer"])).json()
        stored = settings.blob_dir / flight["sha256"][:2] / flight["sha256"][2:4] / flight[
            "sha256"]
        data = bytearray(stored.read_bytes())
        middle = len(data) // 2
        data[middle:middle + 8] = bytes(b ^ 0xFF for b in data[middle:middle + 8])
        stored.write_bytes(bytes(data))

        _run_worker_once(settings)
        flight = client.get(location, headers=_auth(keys["viewer"])).json()
        assert flight["status"] == "rejected"
        assert [reason["code"] for reason in flight["reasons"]] == ["blob_corrupt"]
        with Session(create_engine(settings.effective_database_url)) as s:
            assert s.scalars(select(Job.status)).all() == ["done"]  # no retries of a lost cause


# ---------------------------------------------------------------------------- stale model

def test_active_model_of_an_older_chain_defers_analysis_and_loses_nothing(
        tmp_path, shipped_model) -> None:  # type: ignore[no-untyped-def]
    """A model version trained by the previous chain format must not analyse flights (its
    classifier expects other inputs), nor burn their jobs' attempts: the jobs wait."""
    settings = Settings(data_dir=tmp_path / "data")
    keys = seed_system(settings, {**shipped_model[0], "format": "ema-phm-model/3"})
    with TestClient(create_app(settings)) as client:
        location = _register_and_upload(client, keys, "OLD1")
        _run_worker_once(settings)
        flight = client.get(location, headers=_auth(keys["viewer"])).json()
        assert flight["status"] == "queued"
        with Session(create_engine(settings.effective_database_url)) as s:
            job = s.scalars(select(Job)).one()
            assert job.status == "queued" and job.attempts == 0
            assert "hmsm train" in (job.last_error or "")
