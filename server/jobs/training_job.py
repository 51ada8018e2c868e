"""Train a model version from a design campaign: from the CLI (``hmsm train``) or as the
``train_model`` background job (``POST /api/v1/models/train``)."""

from __future__ import annotations

import json
import os
import shutil
import traceback
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from sqlalchemy.orm import Session, sessionmaker

from server.jobs.context import JobContext
from server.jobs.queue import ClaimedJob
from server.services import models as service

if TYPE_CHECKING:  # pragma: no cover - typing only
    from server.campaigns import Location

__all__ = ["train_into_version", "train_model_job"]


def train_into_version(factory: sessionmaker[Session], version_id: int, design_dir: Location, *,
                       seed: int, activate: bool,
                       progress: Callable[[str, float], None] | None = None) -> dict[str, Any]:
    from server.campaigns import train_from_directory

    try:
        model, report = train_from_directory(design_dir, seed=seed,
                                        jobs=max(1, min(2, os.cpu_count() or 1)),
                                        progress=progress)
    except Exception:
        _fail(factory, version_id)
        raise
    with factory() as session:
        service.finish_version(session=session, version_id=version_id,
                               payload=json.loads(json.dumps(model.to_dict())),
                               training=report, metrics=service.metrics_of(report),
                               make_active=activate)
        session.commit()
    return report


def _fail(factory: sessionmaker[Session], version_id: int) -> None:
    """Mark the version failed with the exception being handled."""
    with factory() as session:
        service.fail_version(session=session, version_id=version_id,
                             error=traceback.format_exc())
        session.commit()


def train_model_job(ctx: JobContext, job: ClaimedJob) -> None:
    """Train on the payload's campaign, simulating it first (``generate``) when it does not
    exist; a campaign the request generated (``remove_campaign``) is removed once training
    has read it, or failed, so at most one lives at a time (training jobs run one by one)."""
    payload = job.payload
    version_id = int(payload["version_id"])
    directory = service.campaign_dir(ctx.settings.data_dir, payload["campaign"])
    try:
        if not (directory / "manifest.json").exists():
            _generate(ctx, version_id, directory, payload)
        train_into_version(ctx.factory, version_id, directory,
                           seed=int(payload.get("seed", 0)),
                           activate=bool(payload.get("activate")))
    finally:
        if payload.get("remove_campaign"):
            shutil.rmtree(directory, ignore_errors=True)


def _generate(ctx: JobContext, version_id: int, directory: Path, payload: dict[str, Any]
              ) -> None:
    """The payload's design campaign, streamed (features kept, one log in 200) once the disk
    is checked; the version fails with whatever stops it."""
    from server.campaigns import FeatureSink
    from sim_worker import run_campaign

    try:
        spec = payload.get("generate")
        if spec is None:
            raise FileNotFoundError(f"campaign {payload['campaign']!r} does not exist")
        service.check_generate_space(ctx.settings.data_dir,
                                     ctx.settings.train_disk_reserve_bytes)
        run_campaign("design", directory, seed=int(spec["seed"]), scale=str(spec["scale"]),
                     workers=1, progress=False, sink=FeatureSink())
    except Exception:
        _fail(ctx.factory, version_id)
        raise
