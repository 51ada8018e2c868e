"""The ``analyze_flight`` job: the PHM chain run on one uploaded flight, its results stored
by :mod:`server.services.analysis`.

Wiring only. Steps: the stored bytes verified against their SHA-256 and decoded, once
(:mod:`server.services.analysis_input`); the whole aircraft's features computed on that log
(:func:`server.phm.recording.log_features`); then, in one transaction, every installed
actuator advanced by the chain from its stored state and the flight marked analysed. Each
step's seconds go to the job's stage clock (``decode``, ``features``, then ``detection``,
``classification`` and ``prognosis`` inside the chain), which the worker stores for
/metrics. When the job is given up (:func:`analysis_given_up`) the flight is marked failed.
"""

from __future__ import annotations

from sqlalchemy.orm import Session

from server.blobstore import BlobStoreUnreachable
from server.jobs.context import Deferred, JobContext
from server.jobs.queue import ClaimedJob
from server.phm.recording import log_features
from server.services import analysis, analysis_input, retention
from server.services import models as model_service

__all__ = ["analyze_flight_job", "analysis_given_up", "analysis_retried"]


def analyze_flight_job(ctx: JobContext, job: ClaimedJob) -> None:
    if job.flight_id is None:
        raise ValueError(f"analyze_flight job {job.id} names no flight")
    with ctx.factory() as session:
        todo = analysis.flight_to_analyse(session=session, flight_id=job.flight_id)
        if todo is None:
            return
        try:
            active = model_service.active_model(session=session)
        except ValueError as exc:  # e.g. a model of an older chain format: wait, lose nothing
            raise Deferred(f"The active model cannot analyse flights: {exc}.") from exc
        if active is None:
            raise Deferred("No active model version: train one with `hmsm train` or "
                           "POST /api/v1/models/train.")
        analysis.mark_analyzing(session=session, flight_id=todo.flight_id)
        session.commit()
    model_id, model = active

    clock = ctx.stages
    with clock.stage("decode"):
        try:
            log = analysis_input.decode_stored(blobs=ctx.blobs, todo=todo,
                                               limits=ctx.settings.decode_limits)
        except analysis_input.Unanalysable as exc:
            _reject(ctx, todo.flight_id, exc.reasons)
            return
        except BlobStoreUnreachable as exc:  # the store's outage is no fault of the flight's
            with ctx.factory() as session:  # queued again, as its job: not analyzing
                analysis.mark_waiting(session=session, flight_id=todo.flight_id,
                                      code="storage_unreachable", message=(
                                          "The flight-log store does not answer; the analysis "
                                          "waits for it and is tried again."))
                session.commit()
            raise Deferred(f"The flight-log store does not answer: {exc}.") from exc
    with clock.stage("features"):
        features = log_features(log)
    del log  # the chain needs only the features: the decoded channels go before it runs
    with ctx.factory() as session:
        # detection, classification and prognosis are timed inside (the chain is one call)
        analysis.store_analysis(session=session, flight_id=todo.flight_id, features=features,
                                model_id=model_id, model=model, clock=clock)
        session.commit()
    keep = ctx.settings.raw_retention_flights
    if keep is not None and todo.aircraft_id is not None:
        with ctx.factory() as session:
            retention.prune_raw(session=session, blobs=ctx.blobs,
                                aircraft_id=todo.aircraft_id, keep=keep)


def _reject(ctx: JobContext, flight_id: int, reasons: list[dict]) -> None:
    with ctx.factory() as session:
        analysis.reject(session=session, flight_id=flight_id, reasons=reasons)
        session.commit()


def analysis_given_up(session: Session, job: ClaimedJob, error: str) -> None:
    """The dead letter of ``analyze_flight``: the flight becomes ``failed`` with the error."""
    if job.flight_id is not None:
        analysis.mark_failed(session=session, flight_id=job.flight_id, error=error,
                             attempts=job.attempts)


def analysis_retried(session: Session, job: ClaimedJob, error: str) -> None:
    """An attempt of ``analyze_flight`` failed and the job is queued again: the flight says
    ``queued`` with the failure as its reason, not ``analyzing`` while it waits."""
    if job.flight_id is not None:
        analysis.mark_retrying(session=session, flight_id=job.flight_id, error=error,
                               attempt=job.attempts, of=job.max_attempts)
