"""``POST /api/v1/models/train`` with ``generate`` is bounded: only the quick scale, a free-disk
check before anything is simulated (507 with the needed and free bytes), and the generated
campaign removed once training has read it. Nothing here simulates a flight."""

from __future__ import annotations

import json
import shutil

from fastapi.testclient import TestClient

from server.app import create_app
from server.config import Settings
from server.jobs.worker import Worker
from server.services.models import GENERATED_CAMPAIGN_BYTES
from tests.api.conftest import auth


def _train(client: TestClient, admin: dict[str, str], **generate: object):  # type: ignore[no-untyped-def]
    return client.post("/api/v1/models/train", headers=admin,
                       json={"campaign": "gen", "generate": {"seed": 1, **generate}})


def _run_job(settings: Settings) -> None:
    worker = Worker(settings)
    assert worker.run_once()
    worker.engine.dispose()


def test_generate_takes_only_the_quick_scale_and_nothing_else(
        client: TestClient, keys: dict[str, str]) -> None:
    admin = auth(keys["admin"])
    for body in ({"scale": "paper"}, {"scale": "protocol"}, {"scale": "ci"},
                 {"per_mode": 100}, {"render_every": 1}):
        r = _train(client, admin, **body)
        assert r.status_code == 422, (body, r.text)
    assert client.get("/api/v1/models", headers=admin).json() == []


def test_generate_without_the_disk_for_it_answers_507_with_needed_and_free_bytes(
        settings: Settings, keys: dict[str, str], client: TestClient) -> None:
    # the same database and data directory, keeping all of today's free disk in reserve
    free = shutil.disk_usage(settings.data_dir).free
    tight = create_app(settings.model_copy(update={"train_disk_reserve_bytes": free}))
    with TestClient(tight, raise_server_exceptions=False) as tight_client:
        r = _train(tight_client, auth(keys["admin"]), scale="quick")
    tight.state.engine.dispose()
    assert r.status_code == 507, r.text
    error = r.json()["error"]
    assert error["code"] == "insufficient_storage"
    assert error["details"]["needed_bytes"] == free + GENERATED_CAMPAIGN_BYTES
    assert 0 < error["details"]["free_bytes"] < error["details"]["needed_bytes"]
    assert "needed" in error["message"] and "free" in error["message"]
    assert client.get("/api/v1/models", headers=auth(keys["admin"])).json() == []
    assert not (settings.data_dir / "campaigns" / "gen").exists()


def test_job_checks_the_disk_again_before_simulating(
        settings: Settings, keys: dict[str, str], client: TestClient) -> None:
    r = _train(client, auth(keys["admin"]))
    assert r.status_code == 202, r.text
    _run_job(settings.model_copy(update={"train_disk_reserve_bytes": 2 ** 62}))
    model = client.get(r.json()["status_url"], headers=auth(keys["admin"])).json()
    assert model["status"] == "failed"
    assert "Not enough free disk" in model["error"] and "needed" in model["error"]
    assert not (settings.data_dir / "campaigns" / "gen").exists()


def test_generated_campaign_is_removed_once_training_has_read_it(
        settings: Settings, keys: dict[str, str], client: TestClient) -> None:
    admin = auth(keys["admin"])
    r = _train(client, admin)
    assert r.status_code == 202, r.text
    # the campaign as the job would find it had its generation finished before a restart:
    # a manifest (one training cannot use, so no simulation is needed to get here)
    campaign = settings.data_dir / "campaigns" / "gen"
    campaign.mkdir(parents=True)
    (campaign / "manifest.json").write_text(json.dumps({"format": "ema-campaign/1",
                                                        "patterns": []}))
    _run_job(settings)
    assert client.get(r.json()["status_url"], headers=admin).json()["status"] == "failed"
    assert not campaign.exists()


def test_an_existing_campaign_is_never_removed(
        settings: Settings, keys: dict[str, str], client: TestClient) -> None:
    admin = auth(keys["admin"])
    campaign = settings.data_dir / "campaigns" / "mine"
    campaign.mkdir(parents=True)
    (campaign / "manifest.json").write_text(json.dumps({"format": "ema-campaign/1",
                                                        "patterns": []}))
    r = client.post("/api/v1/models/train", headers=admin,
                    json={"campaign": "mine", "generate": {"seed": 1}})
    assert r.status_code == 202, r.text
    _run_job(settings)
    assert (campaign / "manifest.json").exists()
