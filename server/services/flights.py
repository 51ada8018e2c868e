"""Flight-log ingest and read-back.

Ingest order (docs/ARCHITECTURE.md, "From an upload to the RUL cone"): the body is already
spooled to a temporary file with its SHA-256; a known digest answers with the existing flight
(idempotent); the file is decoded and checked; the bytes are renamed into the
content-addressed store; only then the flight row (and, for an accepted flight, its analysis
job) is flushed. The caller commits.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from sqlalchemy import func, select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from server.blobstore import BlobStore, SpooledUpload
from server.errors import Conflict, NotFound, Unprocessable
from server.flightlog import (
    OPTIONAL_CHANNELS,
    REQUIRED_CHANNELS,
    FlightLog,
    FlightLogError,
    Issue,
    check_coherence,
    read_flightlog,
)
from server.models import Aircraft, ApiKey, Flight, Job, JobKind
from server.services.fleet import installed_serials

__all__ = ["ingest_flight", "LostRace", "after_lost_race", "get_flight", "flight_codes",
           "list_flights", "decode_flight", "decimated_signals", "ANALYSIS_JOB"]

ANALYSIS_JOB = JobKind.ANALYZE_FLIGHT


def _clean_id(value: Any) -> str | None:
    if value is None:
        return None
    text = str(value)[:64]
    return text if text and all(c.isalnum() or c in "-_." for c in text) else None


def ingest_flight(*, session: Session, blobs: BlobStore, upload: SpooledUpload, kind: str,
                  form_metadata: dict[str, str], uploader: ApiKey) -> tuple[Flight, bool]:
    """Register an uploaded flight; return ``(flight, duplicate)``.

    Raises :class:`Conflict` when an accepted flight with the same (aircraft, flight) has other
    bytes. A file that fails decoding or coherence is stored as ``rejected`` with its reasons.
    """
    existing = session.scalar(select(Flight).where(Flight.sha256 == upload.sha256))
    if existing is not None:
        upload.discard()
        return existing, True

    log: FlightLog | None = None
    issues: list[Issue]
    try:
        log = read_flightlog(upload.read_bytes(), kind=kind, metadata=form_metadata)
    except FlightLogError as exc:
        issues = list(exc.issues)
    tail = log.metadata.aircraft if log else _clean_id(form_metadata.get("aircraft"))
    code = log.metadata.flight if log else _clean_id(form_metadata.get("flight"))
    aircraft_id = (session.scalar(select(Aircraft.id).where(Aircraft.tail == tail))
                   if tail else None)

    if aircraft_id is not None and code is not None:
        clash = session.scalar(select(Flight).where(
            Flight.aircraft_id == aircraft_id, Flight.flight_code == code,
            Flight.status != "rejected"))
        if clash is not None:
            upload.discard()
            if clash.sha256 == upload.sha256:
                # the same bytes, committed by a concurrent upload since the check above
                return clash, True
            raise Conflict(f"Flight '{code}' of '{tail}' was already uploaded with other content.",
                           code="flight_exists", details={"flight_id": clash.id})
    if log is not None:
        issues = check_coherence(log, fleet_serials=installed_serials(session=session, tail=tail))

    blob_path = blobs.commit(upload)
    meta = log.metadata if log else None
    flight = Flight(
        aircraft_id=aircraft_id,
        tail=tail,
        flight_code=code,
        status="rejected" if issues else "queued",
        reasons=[i.as_dict() for i in issues],
        sha256=upload.sha256,
        size_bytes=upload.size,
        blob_path=blob_path,
        content_kind=kind,
        flight_metadata=(meta.to_strings() if meta else
                         {k: str(v)[:200] for k, v in form_metadata.items()}),
        started_at=meta.started_at if meta else None,
        block_hours=meta.block_hours if meta else None,
        uploader_key_id=uploader.id,
    )
    try:
        session.add(flight)
        session.flush()
        if not issues:
            session.add(Job(kind=ANALYSIS_JOB, flight_id=flight.id,
                            lock_key=f"aircraft:{aircraft_id}"))
            session.flush()
    except IntegrityError:
        # A concurrent upload won the race: same bytes (idempotent) or same flight id
        # (conflict); the caller ends this unit of work and asks again (after_lost_race).
        raise LostRace(tail, code) from None
    return flight, False


class LostRace(Conflict):
    """A concurrent upload registered the same bytes or the same (aircraft, flight) first."""

    def __init__(self, tail: str | None, code: str | None):
        super().__init__(f"Flight '{code}' of '{tail}' was uploaded concurrently with other "
                         "content.", code="flight_exists")


def after_lost_race(*, session: Session, race: LostRace, sha256: str) -> Flight:
    """In a new unit of work after :class:`LostRace`: the flight registered with the same
    bytes (the upload was idempotent), or the race's conflict raised."""
    same = session.scalar(select(Flight).where(Flight.sha256 == sha256))
    if same is None:
        raise race
    return same


def get_flight(*, session: Session, flight_id: int) -> Flight:
    flight = session.get(Flight, flight_id)
    if flight is None:
        raise NotFound(f"Flight {flight_id} does not exist.")
    return flight


def flight_codes(*, session: Session, flight_ids: list[int]) -> dict[int, str]:
    """Flight id -> the aircraft's own flight code, for the given flights."""
    if not flight_ids:
        return {}
    return dict(session.execute(select(Flight.id, Flight.flight_code).where(
        Flight.id.in_(flight_ids))).all())


def list_flights(*, session: Session, tail: str | None, status: str | None, limit: int,
                 offset: int) -> tuple[list[Flight], int]:
    query = select(Flight)
    if tail:
        query = query.where(Flight.tail == tail)
    if status:
        query = query.where(Flight.status == status)
    total = session.scalar(select(func.count()).select_from(query.subquery())) or 0
    rows = session.scalars(query.order_by(Flight.id.desc()).limit(limit).offset(offset)).all()
    return list(rows), total


def decode_flight(*, blobs: BlobStore, flight: Flight) -> FlightLog:
    try:
        return read_flightlog(blobs.read(flight.blob_path), kind=flight.content_kind,
                              metadata=flight.flight_metadata)
    except FlightLogError as exc:
        raise Unprocessable("The stored file of this flight cannot be decoded.",
                            code="undecodable", details={"reasons": [i.as_dict() for i in
                                                                     exc.issues]}) from None


def decimated_signals(log: FlightLog, channels: list[str] | None, max_points: int
                      ) -> tuple[int, dict[str, np.ndarray]]:
    """Every n-th sample of the chosen channels so that at most ``max_points`` remain."""
    names = channels or [c for c in REQUIRED_CHANNELS[1:] + OPTIONAL_CHANNELS if c in log.channels]
    unknown = [c for c in names if c not in log.channels]
    if unknown:
        raise NotFound("Channel(s) not in this flight: " + ", ".join(unknown) + ".",
                       code="unknown_channel", details={"channels": unknown})
    step = max(1, math.ceil(log.n_samples / max_points))
    out = {"t": log.channels["t"][::step]}
    out.update({c: log.channels[c][::step] for c in names})
    return step, out
