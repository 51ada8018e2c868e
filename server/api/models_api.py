"""PHM model versions: list, inspect, confusion matrix, activate, train (background job)."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter

from server.api.deps import Admin, Reader, SessionDep, SettingsDep
from server.api.openapi import errors
from server.errors import NotFound, Unprocessable
from server.schemas import IdPath, ModelRead, ModelSummary, TrainAccepted, TrainRequest
from server.services import models as service

router = APIRouter(prefix="/models", tags=["models"])

# ``{model_id:int}`` in the paths: otherwise ``GET /models/train`` would be read as a model id
# (422) rather than answer 405.


@router.get("", response_model=list[ModelSummary], summary="Model versions")
def list_(session: SessionDep, _: Reader) -> list[ModelSummary]:
    return [ModelSummary(id=m.id, name=m.name, status=m.status, active=m.active,
                         accuracy=(m.metrics or {}).get("accuracy"), created_at=m.created_at)
            for m in service.list_versions(session=session)]


@router.get("/{model_id:int}", response_model=ModelRead, summary="One model version")
def get(model_id: IdPath, session: SessionDep, _: Reader) -> ModelRead:
    return ModelRead.model_validate(service.get_version(session=session, version_id=model_id))


@router.get("/{model_id:int}/confusion-matrix", summary="Confusion matrix on the held-out 30 %")
def confusion(model_id: IdPath, session: SessionDep, _: Reader) -> dict[str, Any]:
    row = service.get_version(session=session, version_id=model_id)
    matrix = (row.metrics or {}).get("confusion")
    if not matrix:
        raise NotFound(f"Model {model_id} has no confusion matrix (status {row.status}).",
                       code="no_confusion_matrix")
    return matrix


@router.post("/{model_id:int}/activate", response_model=ModelRead, responses=errors(409),
             summary="Make this version the one the workers use (admin)")
def activate(model_id: IdPath, session: SessionDep, _: Admin) -> ModelRead:
    row = service.activate(session=session, version_id=model_id)
    session.commit()
    return ModelRead.model_validate(row)


@router.post("/train", status_code=202, response_model=TrainAccepted, responses={
                 "409": {"description": (
                     "`training_pending`: a training job is queued or running; one at a time "
                     "(details: job_id, model_id, status).")},
                 "507": {"description": (
                     "`insufficient_storage`: not enough free disk to generate the campaign "
                     "(details: needed_bytes, free_bytes).")}},
             summary="Train a model version from a design campaign, as a background job (admin)")
def train(body: TrainRequest, session: SessionDep, settings: SettingsDep, key: Admin
          ) -> TrainAccepted:
    directory = service.campaign_dir(settings.data_dir, body.campaign)
    generated = not (directory / "manifest.json").exists()
    if generated and body.generate is None:
        raise Unprocessable(f"Campaign '{body.campaign}' does not exist under the data "
                            "directory; give 'generate' to simulate it.", code="no_campaign")
    pending = service.pending_training(session=session)
    if pending is not None:  # before the disk is looked at: a second one would wait anyway
        raise service.training_conflict(pending)
    if generated:
        service.check_generate_space(settings.data_dir, settings.train_disk_reserve_bytes)
    version = service.create_version(session=session, name=body.name or body.campaign,
                                     training={"requested_by": key.name,
                                               "campaign": body.campaign})
    job = service.request_training(
        session=session, version_id=version.id,
        payload={"campaign": body.campaign, "seed": body.seed,
                 "generate": body.generate.model_dump() if body.generate else None,
                 "remove_campaign": generated, "activate": body.activate})
    session.commit()
    return TrainAccepted(model_id=version.id, job_id=job.id,
                         status_url=f"/api/v1/models/{version.id}")
