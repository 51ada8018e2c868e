"""Model versions through the API: train as a background job, inspect, confusion matrix,
activate; errors for what does not exist."""

from __future__ import annotations

import os

import pytest
from fastapi.testclient import TestClient

from server.jobs.worker import Worker
from tests.api.conftest import auth

pytestmark = pytest.mark.slow


def test_train_job_then_confusion_matrix_and_activation(app, client: TestClient,  # type: ignore[no-untyped-def]
                                                         keys: dict[str, str], settings,
                                                         design_campaign_dir) -> None:
    admin, viewer = auth(keys["admin"]), auth(keys["viewer"])
    campaigns = settings.data_dir / "campaigns"
    campaigns.mkdir(parents=True)
    os.symlink(design_campaign_dir, campaigns / "design")

    missing = client.post("/api/v1/models/train", json={"campaign": "nope"}, headers=admin)
    assert missing.status_code == 422 and missing.json()["error"]["code"] == "no_campaign"
    assert client.post("/api/v1/models/train", json={"campaign": "design"},
                       headers=viewer).status_code == 403

    r = client.post("/api/v1/models/train", json={"campaign": "design", "seed": 0}, headers=admin)
    assert r.status_code == 202, r.text
    model_id = r.json()["model_id"]
    assert client.get(f"/api/v1/models/{model_id}", headers=viewer).json()["status"] == "training"
    assert client.get(f"/api/v1/models/{model_id}/confusion-matrix",
                      headers=viewer).status_code == 404

    worker = Worker(settings)
    assert worker.run_once()  # the train_model job
    worker.engine.dispose()
    job = client.get(f"/api/v1/jobs/{r.json()['job_id']}", headers=viewer).json()
    assert job["status"] == "done", job["last_error"]

    model = client.get(f"/api/v1/models/{model_id}", headers=viewer).json()
    assert model["status"] == "ready" and model["active"] is True
    conf = client.get(f"/api/v1/models/{model_id}/confusion-matrix", headers=viewer).json()
    assert set(conf["classes"]) == {"TTS", "DMD", "SE", "BDO", "MTEL", "MTWEAR", "REWEAR"}
    assert len(conf["counts"]) == 7 and conf["accuracy"] == model["metrics"]["accuracy"]
    listed = client.get("/api/v1/models", headers=viewer).json()
    assert [m["id"] for m in listed] == [model_id] and listed[0]["accuracy"] > 0.9

    assert client.post(f"/api/v1/models/{model_id}/activate", headers=viewer).status_code == 403
    assert client.post(f"/api/v1/models/{model_id}/activate",
                       headers=admin).json()["active"] is True
    assert client.get("/api/v1/models/9999", headers=viewer).status_code == 404
