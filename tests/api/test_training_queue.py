"""One pending training at a time (issue 57: an admin queued any number of ``train_model``
jobs, each simulating about 920 flights): while one is queued or running, ``POST
/models/train`` answers 409 ``training_pending`` with that job's id and nothing is made; a
finished or failed one frees the slot. The database's partial unique index holds it against
concurrent requests, on SQLite and PostgreSQL. Nothing here simulates or trains."""

from __future__ import annotations

import json
import threading

import pytest
from fastapi.testclient import TestClient
from sqlalchemy import select
from sqlalchemy.orm import Session, sessionmaker

from server.config import Settings
from server.errors import Conflict
from server.jobs.queue import claim_next, complete
from server.jobs.worker import Worker
from server.models import Job, JobKind, ModelVersion
from server.services import models as service
from tests.api.conftest import auth

TRAIN = "/api/v1/models/train"


def _campaign(settings: Settings, name: str = "design") -> None:
    """A campaign the job can read at once: without patterns, so its training fails at once."""
    directory = settings.data_dir / "campaigns" / name
    directory.mkdir(parents=True)
    (directory / "manifest.json").write_text(json.dumps({"format": "ema-campaign/1",
                                                         "patterns": []}))


def _refused(r, job_id: int, model_id: int, status: str) -> None:  # type: ignore[no-untyped-def]
    assert r.status_code == 409, r.text
    error = r.json()["error"]
    assert error["code"] == "training_pending"
    assert error["details"] == {"job_id": job_id, "model_id": model_id, "status": status}
    assert f"Training job {job_id}" in error["message"]


def test_a_second_training_while_one_is_pending_is_409_naming_it(
        settings: Settings, app, client: TestClient, keys: dict[str, str]) -> None:  # type: ignore[no-untyped-def]
    admin = auth(keys["admin"])
    _campaign(settings)
    first = client.post(TRAIN, json={"campaign": "design"}, headers=admin)
    assert first.status_code == 202, first.text
    job, model = first.json()["job_id"], first.json()["model_id"]
    for body in ({"campaign": "design"}, {"campaign": "design", "seed": 3, "name": "other"},
                 {"campaign": "gen", "generate": {"seed": 1}}):
        _refused(client.post(TRAIN, json=body, headers=admin), job, model, "queued")
    assert [m["id"] for m in client.get("/api/v1/models", headers=admin).json()] == [model]
    assert client.get("/api/v1/jobs", headers=admin).json()["total"] == 1
    assert not (settings.data_dir / "campaigns" / "gen").exists()

    worker = Worker(settings)  # the job fails (a campaign without patterns): the slot is free
    assert worker.run_once()
    worker.engine.dispose()
    assert client.get(f"/api/v1/jobs/{job}", headers=admin).json()["status"] == "dead"
    second = client.post(TRAIN, json={"campaign": "design"}, headers=admin)
    assert second.status_code == 202, second.text
    job, model = second.json()["job_id"], second.json()["model_id"]

    factory = app.state.session_factory  # a worker takes it: running holds the slot too
    claimed = claim_next(factory, worker_id="w1", lease_s=600)
    assert claimed is not None and claimed.id == job
    _refused(client.post(TRAIN, json={"campaign": "design"}, headers=admin), job, model,
             "running")
    with factory() as session:  # it finishes: the slot is free
        assert complete(session, job_id=job, worker_id="w1")
        session.commit()
    assert client.post(TRAIN, json={"campaign": "design"}, headers=admin).status_code == 202


def test_concurrent_requests_queue_one_training(settings: Settings, client: TestClient,
                                                keys: dict[str, str]) -> None:
    admin = auth(keys["admin"])
    _campaign(settings)
    start = threading.Barrier(4)
    answers: list[int] = []

    def request() -> None:
        start.wait()
        answers.append(client.post(TRAIN, json={"campaign": "design"},
                                   headers=admin).status_code)

    threads = [threading.Thread(target=request) for _ in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=60)
    assert sorted(answers) == [202, 409, 409, 409]
    assert len(client.get("/api/v1/models", headers=admin).json()) == 1


def test_a_racing_second_training_is_a_409_not_a_second_job(
        factory: sessionmaker[Session]) -> None:
    with factory() as first:
        version = service.create_version(session=first, name="a", training={})
        job = service.request_training(session=first, version_id=version.id,
                                       payload={"campaign": "c"})
        first.commit()
        job_id, version_id = job.id, version.id
    with factory() as racing:  # its check ran before the first committed: straight to insert
        other = service.create_version(session=racing, name="b", training={})
        with pytest.raises(Conflict) as refused:
            service.add_training_job(session=racing, version_id=other.id,
                                     payload={"campaign": "c"})
    assert refused.value.code == "training_pending"
    assert refused.value.details == {"job_id": job_id, "model_id": version_id,
                                     "status": "queued"}
    with factory() as session:  # the racing request left nothing, its version included
        assert list(session.scalars(select(Job.id).where(
            Job.kind == JobKind.TRAIN_MODEL))) == [job_id]
        assert list(session.scalars(select(ModelVersion.id))) == [version_id]
