"""The real server process: start-up rules and concurrent uploads over loopback."""

from __future__ import annotations

import os
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor

import httpx
from sqlalchemy import create_engine, func, select
from sqlalchemy.orm import Session

from server.auth import create_key
from server.config import Settings
from server.db import make_session_factory, session_scope
from server.migrate import downgrade, upgrade
from server.models import Flight, Job
from tests.flightlog_factory import make_parquet, serials_for
from tests.live_server import running_server


def _env(settings: Settings) -> dict[str, str]:
    env = {"HMSM_DATA_DIR": str(settings.data_dir)}
    if settings.database_url:
        env["HMSM_DATABASE_URL"] = settings.database_url
    return env


def test_twenty_concurrent_uploads_none_lost_or_duplicated(settings: Settings) -> None:
    with running_server(_env(settings)) as url:
        engine = create_engine(settings.effective_database_url)
        with session_scope(make_session_factory(engine)) as s:
            admin = create_key(session=s, name="a", role="admin")[1]
            uploader = create_key(session=s, name="u", role="uploader")[1]
        headers = {"Authorization": f"Bearer {admin}"}
        r = httpx.post(url + "/api/v1/aircraft", headers=headers,
                       json={"tail": "C001", "base": "Turin", "actuators": serials_for("C001")})
        assert r.status_code == 201, r.text
        files = [make_parquet("C001", f"F{i:04d}", seed=i) for i in range(20)]

        def send(data: bytes) -> int:
            resp = httpx.post(url + "/api/v1/flights", content=data, timeout=60, headers={
                "Authorization": f"Bearer {uploader}",
                "Content-Type": "application/vnd.apache.parquet"})
            return resp.status_code

        with ThreadPoolExecutor(max_workers=20) as pool:
            codes = list(pool.map(send, files + files[:5]))  # five sent twice, concurrently
        assert codes[:20].count(202) + codes[:20].count(200) == 20
        assert all(c in (200, 202) for c in codes), codes
        with Session(engine) as s:
            assert s.scalar(select(func.count()).select_from(Flight)) == 20
            assert s.scalar(select(func.count(func.distinct(Flight.flight_code)))) == 20
            assert s.scalar(select(func.count()).select_from(Job)) == 20
        listing = httpx.get(url + "/api/v1/flights?limit=100", headers=headers).json()
        assert listing["total"] == 20
        engine.dispose()


def test_truncated_upload_rejected_and_server_keeps_serving(settings: Settings) -> None:
    with running_server(_env(settings)) as url:
        engine = create_engine(settings.effective_database_url)
        with session_scope(make_session_factory(engine)) as s:
            uploader = create_key(session=s, name="u", role="uploader")[1]
        engine.dispose()
        data = make_parquet("C002", "F1")
        r = httpx.post(url + "/api/v1/flights", content=data[:1000], headers={
            "Authorization": f"Bearer {uploader}",
            "Content-Type": "application/vnd.apache.parquet"})
        assert r.status_code == 422
        assert r.json()["error"]["details"]["reasons"][0]["code"] == "unreadable"
        assert httpx.get(url + "/api/v1/health/ready").status_code == 200


def test_server_behind_schema_refuses_unless_embedded(settings: Settings) -> None:
    from server.migrate import current_revision, head_revision

    url = settings.effective_database_url
    settings.data_dir.mkdir(parents=True, exist_ok=True)
    upgrade(url)
    downgrade(url, "base")
    if settings.is_sqlite:  # the embedded default upgrades itself and serves
        with running_server(_env(settings)) as base_url:
            assert httpx.get(base_url + "/api/v1/health/ready").status_code == 200
    else:
        proc = subprocess.run([sys.executable, "-m", "server.cli", "serve", "--port", "0"],
                              env={**os.environ, **_env(settings)}, capture_output=True,
                              text=True, timeout=60)
        assert proc.returncode == 2
        assert "hmsm db upgrade" in proc.stderr
        upgrade(url)
    engine = create_engine(url)
    assert current_revision(engine) == head_revision()
    engine.dispose()
