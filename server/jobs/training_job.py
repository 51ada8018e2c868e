"""Train a model version from a design campaign: from the CLI (``hmsm train``) or as the
``train_model`` background job (``POST /api/v1/models/train``)."""

from __future__ import annotations

import json
import os
import traceback
from collections.abc import Callable
from pathlib import Path
from typing import Any

from sqlalchemy.orm import Session, sessionmaker

from server.jobs.context import JobContext
from server.jobs.queue import ClaimedJob
from server.services import models as service

__all__ = ["train_into_version", "train_model_job"]


def train_into_version(factory: sessionmaker[Session], version_id: int, design_dir: Path, *,
                       seed: int, activate: bool,
                       progress: Callable[[str, float], None] | None = None) -> dict[str, Any]:
    from server.campaigns import train_from_directory

    try:
        model, report = train_from_directory(design_dir, seed=seed,
                                        jobs=max(1, min(2, os.cpu_count() or 1)),
                                        progress=progress)
    except Exception:
        with factory() as session:
            service.fail_version(session=session, version_id=version_id,
                                 error=traceback.format_exc())
            session.commit()
        raise
    with factory() as session:
        service.finish_version(session=session, version_id=version_id,
                               payload=json.loads(json.dumps(model.to_dict())),
                               training=report, metrics=service.metrics_of(report),
                               make_active=activate)
        session.commit()
    return report


def train_model_job(ctx: JobContext, job: ClaimedJob) -> None:
    payload = job.payload
    directory = service.campaign_dir(ctx.settings.data_dir, payload["campaign"])
    if not (directory / "manifest.json").exists():
        if payload.get("generate") is None:
            raise FileNotFoundError(f"campaign {payload['campaign']!r} does not exist")
        from sim_worker import run_campaign

        run_campaign("design", directory, seed=int(payload["generate"]["seed"]),
                     scale=str(payload["generate"]["scale"]), workers=1, progress=False)
    train_into_version(ctx.factory, int(payload["version_id"]), directory,
                       seed=int(payload.get("seed", 0)), activate=bool(payload.get("activate")))
