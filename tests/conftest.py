"""Shared fixtures: a fresh database per test on SQLite, and on PostgreSQL when
``HMSM_TEST_POSTGRES_URL`` is set (each session creates and drops its own database there)."""

from __future__ import annotations

import os
import shutil
import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest
from sqlalchemy import create_engine, text
from sqlalchemy.orm import Session, sessionmaker

from server.config import Settings
from server.models import Base

PG_URL = os.environ.get("HMSM_TEST_POSTGRES_URL")
BACKENDS = ["sqlite", pytest.param("postgres", marks=[
    pytest.mark.postgres,
    pytest.mark.skipif(not PG_URL, reason="HMSM_TEST_POSTGRES_URL not set"),
])]


def _pg(url: str) -> str:
    return url.replace("postgresql://", "postgresql+psycopg://", 1) if url.startswith(
        "postgresql://") else url


@pytest.fixture(scope="session")
def pg_database() -> Iterator[str]:
    """A new PostgreSQL database for this test session, migrated to head, dropped after."""
    assert PG_URL
    admin = create_engine(_pg(PG_URL), isolation_level="AUTOCOMMIT")
    name = f"hmsm_test_{uuid.uuid4().hex[:12]}"
    with admin.connect() as conn:
        conn.execute(text(f'CREATE DATABASE "{name}"'))
    base, _, _ = _pg(PG_URL).rpartition("/")
    url = f"{base}/{name}"
    from server.migrate import upgrade

    upgrade(url)
    yield url
    with admin.connect() as conn:
        conn.execute(text(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)'))
    admin.dispose()


def truncate_all(url: str) -> None:
    engine = create_engine(url)
    with engine.begin() as conn:
        tables = ", ".join(t.name for t in reversed(Base.metadata.sorted_tables))
        conn.execute(text(f"TRUNCATE {tables} RESTART IDENTITY CASCADE"))
    engine.dispose()


@pytest.fixture(params=BACKENDS)
def backend(request: pytest.FixtureRequest) -> str:
    return request.param


@pytest.fixture(scope="session")
def sqlite_at_head(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """An SQLite database migrated to head once for the session: each test's database starts
    as a copy of it instead of running every migration again (0.4 s a test; the migrations
    themselves are tests/test_migrations.py's, which go down to base and up again)."""
    from server.migrate import upgrade

    template = Settings(data_dir=tmp_path_factory.mktemp("sqlite_at_head"))
    upgrade(template.effective_database_url)
    return template.sqlite_file


@pytest.fixture
def settings(backend: str, tmp_path, request: pytest.FixtureRequest) -> Settings:
    if backend == "postgres":
        url = request.getfixturevalue("pg_database")
        truncate_all(url)
        return Settings(data_dir=tmp_path / "data", database_url=url)
    settings = Settings(data_dir=tmp_path / "data")
    settings.data_dir.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(request.getfixturevalue("sqlite_at_head"), settings.sqlite_file)
    return settings


@pytest.fixture
def factory(settings: Settings) -> Iterator[sessionmaker[Session]]:
    """A session factory on the chosen backend's database, migrated to head."""
    from server.db import make_engine, make_session_factory
    from server.migrate import upgrade

    settings.data_dir.mkdir(parents=True, exist_ok=True)
    upgrade(settings.effective_database_url)
    engine = make_engine(settings.effective_database_url)
    yield make_session_factory(engine)
    engine.dispose()


# ---------------------------------------------------------------------------------------------
# simulated campaigns and a trained model, once per session (PHM_CAMPAIGN_DIR reuses a cache)
# ---------------------------------------------------------------------------------------------

DESIGN_SEED, VERIFICATION_SEED = 1, 2


def make_campaign(kind: str, seed: int, root) -> object:  # type: ignore[no-untyped-def]
    """``root/<kind>_<seed>``: a quick campaign, generated unless its manifest exists."""
    import fcntl
    from pathlib import Path

    out = Path(root) / f"{kind}_{seed}"
    # one writer: the suite's xdist workers share the root, the first makes it, the others wait
    with open(Path(root) / f"{kind}_{seed}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not (out / "manifest.json").exists():
            from sim_worker import run_campaign

            run_campaign(kind, out, seed=seed, scale="quick", workers=os.cpu_count() or 1,
                         progress=False)
    return out


@pytest.fixture(scope="session")
def campaign_root(tmp_path_factory: pytest.TempPathFactory):  # type: ignore[no-untyped-def]
    from pathlib import Path

    env = os.environ.get("PHM_CAMPAIGN_DIR")
    if env:
        Path(env).mkdir(parents=True, exist_ok=True)
        return Path(env)
    if os.environ.get("PYTEST_XDIST_WORKER"):  # one root for the run's workers (pytest -n)
        shared = tmp_path_factory.getbasetemp().parent / "phm_campaigns"
        shared.mkdir(exist_ok=True)
        return shared
    return tmp_path_factory.mktemp("phm_campaigns")


@pytest.fixture(scope="session")
def design_campaign_dir(campaign_root):  # type: ignore[no-untyped-def]
    return make_campaign("design", DESIGN_SEED, campaign_root)


@pytest.fixture(scope="session")
def verification_campaign_dir(campaign_root):  # type: ignore[no-untyped-def]
    return make_campaign("verification", VERIFICATION_SEED, campaign_root)


@pytest.fixture(scope="session")
def shipped_model():  # type: ignore[no-untyped-def]
    """(model JSON, training report) of the model shipped in the package: the same chain as
    ``trained_model`` (``tests/test_demo.py`` holds them equal), read in milliseconds instead
    of simulating and training for minutes. Tests that need *a* model use this one."""
    from server.demo_model import load_demo_model

    doc = load_demo_model()
    return doc["payload"], doc["training"]


@pytest.fixture(scope="session")
def trained_model(design_campaign_dir):  # type: ignore[no-untyped-def]
    """(model JSON, training report) of the PHM chain fitted on the quick design campaign:
    only for the ``slow`` tests about training itself (the others use ``shipped_model``)."""
    import json

    from server.campaigns import train_from_directory

    model, report = train_from_directory(design_campaign_dir, seed=0, jobs=os.cpu_count() or 1)
    return json.loads(json.dumps(model.to_dict())), report


# ---------------------------------------------------------------------------------------------
# an S3 server over HTTP (moto's), for the object-store backend of the blob store
# ---------------------------------------------------------------------------------------------

@pytest.fixture(scope="session")
def s3_server():  # type: ignore[no-untyped-def]
    """moto's S3 server for the session, with the AWS_* variables boto3 reads set."""
    from tests.s3_server import AWS_ENV, MotoS3

    with pytest.MonkeyPatch.context() as mp:
        for name, value in AWS_ENV.items():
            mp.setenv(name, value)
        server = MotoS3()
        server.start()
        yield server
        server.stop()
