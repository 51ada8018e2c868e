"""PHM model versions: store trained models as JSON, list them, activate one, and decode the
one the workers run (cached per database and version)."""

from __future__ import annotations

import shutil
import threading
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NamedTuple, cast

from sqlalchemy import Engine, select, update
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from server.errors import Conflict, NotFound, StorageUnavailable
from server.models import Job, JobKind, ModelVersion, utcnow
from server.phm.chain import PhmModel, is_model_document, read_model_document
from server.phm.detection import FaultDetector
from server.vocabulary import JobStatus, ModelVersionStatus

__all__ = ["create_version", "finish_version", "fail_version", "activate", "get_version",
           "active_version", "list_versions", "metrics_of", "store_trained", "active_model",
           "decoded_model", "DetectorLevels", "detector_levels", "request_training",
           "pending_training", "training_conflict", "add_training_job",
           "campaign_dir", "GENERATED_CAMPAIGN_BYTES", "check_generate_space"]

#: what a design campaign generated for training (quick scale, 60 patterns) may take on disk:
#: it is streamed (features kept, the log of flight 0 of each pattern and then one in 200),
#: about 120 MB, as the demo's streamed quick verification campaign took 59 MB for its 31
#: patterns (README); twice that is reserved
GENERATED_CAMPAIGN_BYTES = 256 * 1024 * 1024

#: decoded models, keyed by (database URL, model version id): a version id alone names
#: another model in another database served by the same process
_DECODED: dict[tuple[str, int], PhmModel] = {}
_DECODED_LOCK = threading.Lock()
_DECODED_MAX = 4


def create_version(*, session: Session, name: str, training: dict[str, Any]) -> ModelVersion:
    row = ModelVersion(name=name, status=ModelVersionStatus.TRAINING, active=False, payload={},
                       training=training, metrics={})
    session.add(row)
    session.flush()
    return row


def finish_version(*, session: Session, version_id: int, payload: dict[str, Any],
                   training: dict[str, Any], metrics: dict[str, Any], make_active: bool
                   ) -> ModelVersion:
    row = get_version(session=session, version_id=version_id)
    row.payload, row.training, row.metrics = payload, training, metrics
    row.status, row.finished_at = ModelVersionStatus.READY, utcnow()
    session.flush()
    if make_active:
        activate(session=session, version_id=version_id)
    return row


def fail_version(*, session: Session, version_id: int, error: str) -> None:
    row = get_version(session=session, version_id=version_id)
    row.status, row.error, row.finished_at = ModelVersionStatus.FAILED, error[-4000:], utcnow()


def activate(*, session: Session, version_id: int) -> ModelVersion:
    row = get_version(session=session, version_id=version_id)
    if row.status != ModelVersionStatus.READY:
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


def active_version(*, session: Session) -> ModelVersion | None:
    return session.scalar(select(ModelVersion).where(ModelVersion.active.is_(True)))


def decoded_model(*, session: Session, version_id: int) -> PhmModel:
    """The chain of a model version, decoded once per process (the document is immutable
    once the version is ready). Raises ValueError for a document the chain cannot run."""
    key = (str(cast(Engine, session.get_bind()).url), int(version_id))  # bound to an engine
    with _DECODED_LOCK:
        if key not in _DECODED:
            payload = get_version(session=session, version_id=version_id).payload
            if len(_DECODED) >= _DECODED_MAX:
                _DECODED.clear()
            _DECODED[key] = read_model_document(payload)
        return _DECODED[key]


def active_model(*, session: Session) -> tuple[int, PhmModel] | None:
    """(version id, decoded chain) of the active model version, or None if there is none."""
    version_id = session.scalar(select(ModelVersion.id).where(ModelVersion.active.is_(True)))
    if version_id is None:
        return None
    return int(version_id), decoded_model(session=session, version_id=int(version_id))


class DetectorLevels(NamedTuple):
    band: float  # healthy band [standard errors]
    threshold: float  # single-flight alarm threshold [standard errors]
    alarm_confidence: float  # the detection confidence at which the unit alarms


def detector_levels(*, session: Session, version_id: int | None, features: Sequence[str]
                    ) -> DetectorLevels:
    """The levels of a model version's detector for the plotted features: the one-flight
    band (median over the features), that band plus the standard errors at which the alarm
    confidence is reached, and that confidence. Without a usable model, the detector's
    defaults."""
    version = None if version_id is None else session.get(ModelVersion, version_id)
    if version is None or not is_model_document(version.payload):
        default = FaultDetector()  # unfitted: its band floor and alarm levels
        return DetectorLevels(default.band_floor, default.band_floor + default.z_alarm,
                              default.alarm_confidence)
    detector = decoded_model(session=session, version_id=version.id).detector
    bands = detector.bands()
    values = sorted(bands[f][0] for f in features if f in bands and bands[f])
    band = values[len(values) // 2] if values else detector.band_floor
    return DetectorLevels(band, band + detector.z_alarm, detector.alarm_confidence)


def pending_training(*, session: Session) -> Job | None:
    """The training job queued or running, if any (at most one: ``PENDING_TRAINING``)."""
    return session.scalar(select(Job).where(Job.kind == JobKind.TRAIN_MODEL, Job.status.in_(
        (JobStatus.QUEUED, JobStatus.RUNNING))).order_by(Job.id).limit(1))


def training_conflict(job: Job | None) -> Conflict:
    """409 ``training_pending`` naming the pending job and its model version."""
    if job is None:  # it finished between the refused insert and this look: try again
        return Conflict("Another training was requested at the same time; try again.",
                        code="training_pending")
    version_id = (job.payload or {}).get("version_id")
    return Conflict(
        f"Training job {job.id} (model version {version_id}) is {job.status}: one training is "
        "pending at a time. Request another once it is done or has failed "
        f"(GET /api/v1/jobs/{job.id}).", code="training_pending",
        details={"job_id": job.id, "model_id": version_id, "status": str(job.status)})


def request_training(*, session: Session, version_id: int, payload: dict[str, Any]) -> Job:
    """Queue the training job of a model version: only while no other is queued or running
    (each may simulate a design campaign of about 920 flights), else 409 naming that one."""
    pending = pending_training(session=session)
    if pending is not None:
        raise training_conflict(pending)
    return add_training_job(session=session, version_id=version_id, payload=payload)


def add_training_job(*, session: Session, version_id: int, payload: dict[str, Any]) -> Job:
    """The training job added and flushed. A concurrent request whose check ran before this
    one committed is refused by the partial unique index ``uq_jobs_pending_training``: its
    whole transaction is rolled back (the version made for it too) and 409 names the job
    that holds the slot. Jobs of one lock key run one at a time besides."""
    job = Job(kind=JobKind.TRAIN_MODEL, lock_key=JobKind.TRAIN_MODEL, max_attempts=1,
              payload={**payload, "version_id": version_id})
    session.add(job)
    try:
        session.flush()
    except IntegrityError:
        session.rollback()
        raise training_conflict(pending_training(session=session)) from None
    return job


def campaign_dir(data_dir: Path, name: str) -> Path:
    """A campaign directory under ``<data_dir>/campaigns`` (names are validated by the API)."""
    return data_dir / "campaigns" / name


def check_generate_space(data_dir: Path, reserve_bytes: int) -> None:
    """Refuse (507 ``insufficient_storage``) to generate a design campaign unless the data
    directory's file system has room for it and ``reserve_bytes`` besides (flight logs and
    the database need the rest)."""
    existing = next(p for p in (data_dir, *data_dir.parents) if p.exists())
    free = shutil.disk_usage(existing).free
    needed = GENERATED_CAMPAIGN_BYTES + reserve_bytes
    if free < needed:
        raise StorageUnavailable(
            f"Not enough free disk to generate a design campaign: {needed} bytes needed "
            f"({GENERATED_CAMPAIGN_BYTES} for the campaign, {reserve_bytes} kept free), "
            f"{free} free.", code="insufficient_storage",
            details={"needed_bytes": needed, "free_bytes": free})
