"""PHM model versions: store trained models as JSON, list them, activate one."""

from __future__ import annotations

from typing import Any

from sqlalchemy import select, update
from sqlalchemy.orm import Session

from server.errors import Conflict, NotFound
from server.models import ModelVersion, utcnow

__all__ = ["create_version", "finish_version", "fail_version", "activate", "get_version",
           "list_versions", "metrics_of", "store_trained"]


def create_version(*, session: Session, name: str, training: dict[str, Any]) -> ModelVersion:
    row = ModelVersion(name=name, status="training", active=False, payload={},
                       training=training, metrics={})
    session.add(row)
    session.flush()
    return row


def finish_version(*, session: Session, version_id: int, payload: dict[str, Any],
                   training: dict[str, Any], metrics: dict[str, Any], make_active: bool
                   ) -> ModelVersion:
    row = get_version(session=session, version_id=version_id)
    row.payload, row.training, row.metrics = payload, training, metrics
    row.status, row.finished_at = "ready", utcnow()
    session.flush()
    if make_active:
        activate(session=session, version_id=version_id)
    return row


def fail_version(*, session: Session, version_id: int, error: str) -> None:
    row = get_version(session=session, version_id=version_id)
    row.status, row.error, row.finished_at = "failed", error[-4000:], utcnow()


def activate(*, session: Session, version_id: int) -> ModelVersion:
    row = get_version(session=session, version_id=version_id)
    if row.status != "ready":
        raise Conflict(f"Model {version_id} is {row.status}; only a ready model can be "
                       "activated.", code="model_not_ready")
    session.execute(update(ModelVersion).where(ModelVersion.id != version_id)
                    .values(active=False))
    row.active = True
    session.flush()
    return row


def get_version(*, session: Session, version_id: int) -> ModelVersion:
    row = session.get(ModelVersion, version_id)
    if row is None:
        raise NotFound(f"Model version {version_id} does not exist.")
    return row


def list_versions(*, session: Session) -> list[ModelVersion]:
    return list(session.scalars(select(ModelVersion).order_by(ModelVersion.id.desc())))


def metrics_of(report: dict[str, Any]) -> dict[str, Any]:
    """What the models page and API show of a training report: held-out accuracy, confusion."""
    classifier = report.get("classifier") or {}
    conf = classifier.get("confusion") or {}
    return {"accuracy": conf.get("accuracy"), "confusion": conf,
            "calibration": classifier.get("calibration")}


def store_trained(*, session: Session, name: str, payload: dict[str, Any],
                  report: dict[str, Any], make_active: bool) -> ModelVersion:
    """A ready model version from a trained model's JSON and its training report."""
    row = create_version(session=session, name=name, training={})
    return finish_version(session=session, version_id=row.id, payload=payload, training=report,
                          metrics=metrics_of(report), make_active=make_active)
