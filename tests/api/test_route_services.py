"""The service seams the routes go through (server.api imports no SQLAlchemy): the readiness
probe's ping, the one-alarm read-back, the keys and jobs read-backs."""

from __future__ import annotations

from pathlib import Path

import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient

from server.auth import keys_by_id, list_keys
from server.db import DatabaseUnavailable, make_engine, ping, session_scope
from server.errors import NotFound
from server.services import health as health_service
from server.services import jobs as job_service
from tests.api.conftest import auth


def test_readiness_answers_503_when_the_database_does_not(app: FastAPI, client: TestClient,
                                                         tmp_path: Path) -> None:
    away = make_engine(f"sqlite:///{tmp_path / 'no-such-dir' / 'hmsm.db'}")
    answering, app.state.engine = app.state.engine, away
    try:
        r = client.get("/api/v1/health/ready")
    finally:
        app.state.engine = answering
        away.dispose()
    assert r.status_code == 503 and r.json()["error"]["code"] == "database_unavailable"


def test_ping_names_an_unreachable_database_in_its_own_terms(tmp_path: Path) -> None:
    away = make_engine(f"sqlite:///{tmp_path / 'no-such-dir' / 'hmsm.db'}")
    with pytest.raises(DatabaseUnavailable):
        ping(away)
    away.dispose()


def test_an_unknown_alarm_is_not_found(app: FastAPI) -> None:
    with session_scope(app.state.session_factory) as session, pytest.raises(NotFound):
        health_service.alarm_row(session=session, alarm_id=987654)


def test_key_and_job_read_backs(app: FastAPI, client: TestClient, keys: dict[str, str]
                                ) -> None:
    with session_scope(app.state.session_factory) as session:
        every = list_keys(session=session)
        assert [k.id for k in every] == sorted(k.id for k in every) and len(every) == len(keys)
        assert keys_by_id(session=session, key_ids=[None]) == {}
        assert set(keys_by_id(session=session, key_ids=[every[0].id, None])) == {every[0].id}
        assert job_service.list_jobs(session=session, status=None, flight_id=None, limit=5,
                                     offset=0) == ([], 0)
        with pytest.raises(NotFound):
            job_service.get_job(session=session, job_id=987654)
    assert client.get("/api/v1/jobs/987654", headers=auth(keys["viewer"])).status_code == 404
