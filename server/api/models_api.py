"""PHM model versions: list, inspect, confusion matrix, activate, train (background job)."""

from __future__ import annotations

from datetime import datetime
from typing import Any, Literal

from fastapi import APIRouter
from pydantic import BaseModel, ConfigDict, Field

from server.api.deps import Admin, Reader, SessionDep, SettingsDep
from server.api.openapi import errors
from server.errors import NotFound, Unprocessable
from server.services import models as service

router = APIRouter(prefix="/models", tags=["models"])

# No leading dot: "." and ".." would name the campaigns directory or the data directory.
# ``{model_id:int}`` in the paths: otherwise ``GET /models/train`` would be read as a model id
# (422) rather than answer 405.
_NAME = r"^[A-Za-z0-9_-][A-Za-z0-9._-]{0,63}$"


class ModelRead(BaseModel):
    model_config = ConfigDict(from_attributes=True)
    id: int
    name: str
    status: str
    active: bool
    metrics: dict[str, Any]
    training: dict[str, Any]
    error: str | None
    created_at: datetime
    finished_at: datetime | None


class ModelSummary(BaseModel):
    id: int
    name: str
    status: str
    active: bool
    accuracy: float | None
    created_at: datetime


class GenerateSpec(BaseModel):
    model_config = ConfigDict(extra="forbid")
    seed: int = Field(ge=0, le=2**31 - 1, strict=True)
    # quick alone: about 920 flights in 3 minutes on 2 cores, streamed (docs/SECURITY.md);
    # paper (about 8 GB) and protocol (hours) campaigns are for `hmsm campaign` / `protocol`
    scale: Literal["quick"] = Field("quick", description=(
        "Only quick; larger campaigns come from the command line (`hmsm campaign`)."))


class TrainRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")
    campaign: str = Field(pattern=_NAME, description=(
        "Design campaign directory name under HMSM_DATA_DIR/campaigns."))
    generate: GenerateSpec | None = Field(None, description=(
        "Simulate the design campaign first if it does not exist yet; it is removed once "
        "training has read it."))
    seed: int = Field(0, ge=0, le=2**31 - 1, strict=True,
                      description="Seed of the 70/30 split.")
    name: str | None = Field(None, pattern=_NAME)
    activate: bool = True


class TrainAccepted(BaseModel):
    model_id: int
    job_id: int
    status_url: str


@router.get("", response_model=list[ModelSummary], summary="Model versions")
def list_(session: SessionDep, _: Reader) -> list[ModelSummary]:
    return [ModelSummary(id=m.id, name=m.name, status=m.status, active=m.active,
                         accuracy=(m.metrics or {}).get("accuracy"), created_at=m.created_at)
            for m in service.list_versions(session=session)]


@router.get("/{model_id:int}", response_model=ModelRead, summary="One model version")
def get(model_id: int, session: SessionDep, _: Reader) -> ModelRead:
    return ModelRead.model_validate(service.get_version(session=session, version_id=model_id))


@router.get("/{model_id:int}/confusion-matrix", summary="Confusion matrix on the held-out 30 %")
def confusion(model_id: int, session: SessionDep, _: Reader) -> dict[str, Any]:
    row = service.get_version(session=session, version_id=model_id)
    matrix = (row.metrics or {}).get("confusion")
    if not matrix:
        raise NotFound(f"Model {model_id} has no confusion matrix (status {row.status}).",
                       code="no_confusion_matrix")
    return matrix


@router.post("/{model_id:int}/activate", response_model=ModelRead, responses=errors(409),
             summary="Make this version the one the workers use (admin)")
def activate(model_id: int, session: SessionDep, _: Admin) -> ModelRead:
    row = service.activate(session=session, version_id=model_id)
    session.commit()
    return ModelRead.model_validate(row)


@router.post("/train", status_code=202, response_model=TrainAccepted, responses={
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
