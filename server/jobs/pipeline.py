"""Per-flight analysis (the ``analyze_flight`` job).

Steps: verify the stored bytes against their SHA-256, decode, and (as the PHM stages land) run
features, detection, classification and prognosis for each actuator, storing results keyed by
(actuator, flight) so a job that runs twice writes nothing twice.
"""

from __future__ import annotations

import hashlib

from sqlalchemy import update

from server.flightlog import FlightLogError, read_flightlog
from server.jobs.queue import ClaimedJob
from server.jobs.worker import JobContext
from server.models import Flight, utcnow

__all__ = ["analyze_flight"]


def _set_status(ctx: JobContext, flight_id: int, status: str, reasons: list | None = None
                ) -> None:
    values: dict = {"status": status, "updated_at": utcnow()}
    if reasons is not None:
        values["reasons"] = reasons
    with ctx.factory() as session:
        session.execute(update(Flight).where(Flight.id == flight_id).values(**values))
        session.commit()


def analyze_flight(ctx: JobContext, job: ClaimedJob) -> None:
    assert job.flight_id is not None
    with ctx.factory() as session:
        flight = session.get(Flight, job.flight_id)
        if flight is None:
            return
        blob_path, sha, kind, meta = (flight.blob_path, flight.sha256, flight.content_kind,
                                      dict(flight.flight_metadata))
    _set_status(ctx, job.flight_id, "analyzing")
    data = ctx.blobs.read(blob_path)
    if hashlib.sha256(data).hexdigest() != sha:
        # The bytes changed on disk after ingest: nothing to retry, the flight is unusable.
        _set_status(ctx, job.flight_id, "rejected", [{
            "code": "blob_corrupt", "message": "The stored file no longer matches its SHA-256; "
            "it was corrupted on disk after upload.", "details": {"sha256": sha}}])
        return
    try:
        read_flightlog(data, kind=kind, metadata=meta)
    except FlightLogError as exc:
        _set_status(ctx, job.flight_id, "rejected", [i.as_dict() for i in exc.issues])
        return
    _set_status(ctx, job.flight_id, "analyzed")
