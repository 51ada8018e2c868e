"""The running system: API + analysis workers + the sim worker, on SQLite and PostgreSQL.

A test-station fault flows through simulated flights to an alarm of the right class and a
prognosis; a worker killed with SIGKILL mid-job loses nothing; two workers never analyse one
aircraft at once.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager

import httpx
import pytest
from sqlalchemy import create_engine, func, select
from sqlalchemy.orm import Session

from server.auth import create_key
from server.config import Settings
from server.db import make_session_factory, session_scope
from server.migrate import upgrade
from server.models import HealthRecord, Job
from server.services import models as model_service
from sim_worker.service import Api, SimFleetRunner
from tests.conftest import BACKENDS
from tests.live_server import running_server

pytestmark = pytest.mark.slow


def _env(settings: Settings) -> dict[str, str]:
    env = {"HMSM_DATA_DIR": str(settings.data_dir)}
    if settings.database_url:
        env["HMSM_DATABASE_URL"] = settings.database_url
    return env


@pytest.fixture
def system(settings: Settings, shipped_model):  # type: ignore[no-untyped-def]
    """Database at head with the trained model active, and keys for every role."""
    settings.data_dir.mkdir(parents=True, exist_ok=True)
    upgrade(settings.effective_database_url)
    engine = create_engine(settings.effective_database_url)
    factory = make_session_factory(engine)
    payload, report = shipped_model
    with session_scope(factory) as s:
        model_service.store_trained(session=s, name="e2e", payload=payload, report=report,
                                    make_active=True)
        keys = {r: create_key(session=s, name=f"e2e-{r}", role=r)[1]
                for r in ("admin", "operator", "viewer")}
    yield settings, engine, keys
    engine.dispose()


@contextmanager
def worker(settings: Settings, *args: str, extra_env: dict[str, str] | None = None
           ) -> Iterator[subprocess.Popen[bytes]]:
    proc = subprocess.Popen([sys.executable, "-m", "server.cli", "worker", *args],
                            env={**os.environ, **_env(settings), **(extra_env or {})},
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        yield proc
    finally:
        if proc.poll() is None:
            proc.terminate()
            proc.wait(timeout=30)


def wait_until(predicate, timeout_s: float, what: str) -> None:  # type: ignore[no-untyped-def]
    deadline = time.monotonic() + timeout_s
    while not predicate():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.2)


def pending_flights(url: str, key: str) -> int:
    h = {"Authorization": f"Bearer {key}"}
    return sum(httpx.get(f"{url}/api/v1/flights?status={s}&limit=1", headers=h).json()["total"]
               for s in ("received", "queued", "analyzing"))


def test_injected_faults_raise_classified_alarms_and_prognoses(system) -> None:  # type: ignore[no-untyped-def]
    settings, engine, keys = system
    with running_server(_env(settings)) as url, worker(settings):
        api = Api(url, keys["admin"])
        runner = SimFleetRunner(api, n_aircraft=2, rate_per_min=1e6, seed=5, duration_s=60)
        runner.register_fleet()
        op = {"Authorization": f"Bearer {keys['operator']}"}
        for body in ({"aircraft": "SIM01", "position": "WT", "fault_mode": "BDO",
                      "onset_flight": 3},
                     {"aircraft": "SIM02", "position": "WL1", "fault_mode": "MTWEAR",
                      "onset_flight": 1, "time_to_failure_flights": 30}):
            assert httpx.post(f"{url}/api/v1/test-station/injections", json=body,
                              headers=op).status_code == 201
        assert runner.run(max_flights=2 * 12) == 24
        wait_until(lambda: pending_flights(url, keys["viewer"]) == 0, 240, "analysis")

        viewer = {"Authorization": f"Bearer {keys['viewer']}"}
        alarms = httpx.get(f"{url}/api/v1/alarms", headers=viewer).json()["items"]
        by_actuator = {(a["aircraft"], a["position"]): a for a in alarms}
        assert by_actuator[("SIM01", "WT")]["fault_mode"] == "BDO"
        wear = by_actuator[("SIM02", "WL1")]
        assert wear["fault_mode"] == "MTWEAR"
        # every alarm names its unit; a winglet drive's maybe with its partner, less likely
        assert by_actuator[("SIM01", "WT")]["isolation"] == {"WT": 1.0}
        assert max(wear["isolation"], key=wear["isolation"].get) == "WL1"
        prognoses = httpx.get(f"{url}/api/v1/actuators/{wear['actuator_id']}/prognoses",
                              headers=viewer).json()
        assert isinstance(prognoses, list), prognoses
        assert prognoses and [q for q, _ in prognoses[-1]["distribution"]["quantiles"]] == [
            0.05, 0.25, 0.5, 0.75, 0.95]
        injections = httpx.get(f"{url}/api/v1/test-station/injections",
                               headers=viewer).json()["items"]
        assert {i["status"] for i in injections} == {"active"}
        truth = httpx.get(f"{url}/api/v1/test-station/injections/"
                          f"{injections[0]['id']}/ground-truth", headers=viewer).json()
        assert len(truth) >= 9
        flights = httpx.get(f"{url}/api/v1/flights?limit=100", headers=viewer).json()
        assert flights["total"] == 24
        assert {f["status"] for f in flights["items"]} == {"analyzed"}


def _kill_mid_job(pid: int, running: Callable[[], bool]) -> None:
    """SIGKILL the worker while a job of its is running: frozen first (SIGSTOP), so that the
    job it was seen running cannot finish between the look and the kill."""
    for _ in range(100):
        wait_until(running, 60, "a running job")
        os.kill(pid, signal.SIGSTOP)
        if running():
            os.kill(pid, signal.SIGKILL)
            return
        os.kill(pid, signal.SIGCONT)  # it finished that job in between: catch the next
    raise AssertionError("never caught the worker mid-job")


@pytest.fixture(params=["local", "s3"])
def blob_env(request: pytest.FixtureRequest) -> dict[str, str]:
    """Where the API and the workers keep flight logs: the data directory, or a bucket of
    moto's S3 server over HTTP (HMSM_BLOB_URL)."""
    if request.param == "local":
        return {}
    if request.getfixturevalue("backend") != "sqlite":
        # the store does not depend on the database: PostgreSQL with the bucket is
        # tests/api/test_object_store.py's, and the suite's time is kept
        pytest.skip("the object store's kill test runs on SQLite")
    s3 = request.getfixturevalue("s3_server")
    return {"HMSM_BLOB_URL": f"s3://{s3.new_bucket()}/logs", "HMSM_S3_ENDPOINT_URL": s3.endpoint}


def test_worker_killed_mid_job_loses_and_duplicates_nothing(system, blob_env) -> None:  # type: ignore[no-untyped-def]
    settings, engine, keys = system
    with running_server({**_env(settings), **blob_env}) as url:
        api = Api(url, keys["admin"])
        runner = SimFleetRunner(api, n_aircraft=1, rate_per_min=1e6, seed=9, duration_s=60)
        runner.register_fleet()
        runner.run(max_flights=6)
        with worker(settings, "--lease", "2", extra_env=blob_env) as doomed:
            def running() -> bool:
                with Session(engine) as s:
                    return s.scalar(select(Job.id).where(Job.status == "running")) is not None

            _kill_mid_job(doomed.pid, running)
            doomed.wait(timeout=10)
        with Session(engine) as s:
            stranded = s.scalars(select(Job).where(Job.status == "running")).all()
            assert len(stranded) == 1  # its lease will expire
            stranded_id = stranded[0].id
        with worker(settings, "--lease", "2", extra_env=blob_env):
            wait_until(lambda: pending_flights(url, keys["viewer"]) == 0, 180, "re-analysis")
        with Session(engine) as s:
            jobs = s.scalars(select(Job)).all()
            assert {j.status for j in jobs} == {"done"} and len(jobs) == 6
            assert s.get(Job, stranded_id).attempts == 2
            assert s.scalar(select(func.count()).select_from(HealthRecord)) == 6 * 3
            indices = s.scalars(select(HealthRecord.flight_index)
                                .order_by(HealthRecord.flight_index)).all()
            assert indices == sorted([i for i in range(1, 7) for _ in range(3)])
    if blob_env:  # the six logs are in the bucket, none under the data directory
        bucket = blob_env["HMSM_BLOB_URL"].removeprefix("s3://").split("/")[0]
        from tests.s3_server import MotoS3

        assert len(MotoS3.keys_at(blob_env["HMSM_S3_ENDPOINT_URL"], bucket)) == 6
        assert not [f for f in settings.data_dir.rglob("*.parquet")]


# several workers share a queue on PostgreSQL (SKIP LOCKED): this test has no SQLite variant
@pytest.mark.parametrize("backend", [p for p in BACKENDS if getattr(p, "values", ("",))[0]
                                     == "postgres"])
def test_two_workers_never_analyse_one_aircraft_at_once(system) -> None:  # type: ignore[no-untyped-def]
    settings, engine, keys = system
    with running_server(_env(settings)) as url:
        api = Api(url, keys["admin"])
        runner = SimFleetRunner(api, n_aircraft=3, rate_per_min=1e6, seed=11, duration_s=30)
        runner.register_fleet()
        runner.run(max_flights=12)
        with worker(settings, "--concurrency", "2"):
            wait_until(lambda: pending_flights(url, keys["viewer"]) == 0, 180, "analysis")
        with Session(engine) as s:
            jobs = s.scalars(select(Job).order_by(Job.id)).all()
        assert len(jobs) == 12 and {j.status for j in jobs} == {"done"}
        assert len({j.locked_by for j in jobs}) == 2  # both workers took part
        for key in {j.lock_key for j in jobs}:
            mine = sorted((j.started_at, j.finished_at) for j in jobs if j.lock_key == key)
            assert all(a[1] <= b[0] for a, b in zip(mine, mine[1:], strict=False)), key
