"""Flight-log ingest and read-back.

Ingest order (docs/ARCHITECTURE.md, "From an upload to the RUL cone"): the body is already
spooled to a temporary file with its SHA-256; an upload the same as an accepted (not rejected)
flight answers with that flight (idempotent; :func:`upload_key` says what "the same" is); the
file is decoded and checked; the bytes are renamed into the content-addressed store; only then
the flight row (and, for an accepted flight, its analysis job) is flushed. The caller commits.

A rejected flight neither holds its (aircraft, flight) slot nor makes its upload an accepted
duplicate: the same bytes sent again (say, once the aircraft is registered) are evaluated
afresh; accepted now, they give a new row and the rejected one stays, for forensics; rejected
again, they give no new row nor file: the rejected row is brought up to date and answered. A
rejected file is kept only within its key's quota (:mod:`server.services.storage`).
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from sqlalchemy import delete, func, select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from server.blobstore import BlobStore, SpooledUpload
from server.errors import Conflict, Gone, NotFound, PayloadTooLarge, Unprocessable
from server.flightlog import (
    DEFAULT_DECODE_LIMITS,
    OPTIONAL_CHANNELS,
    REQUIRED_CHANNELS,
    DecodeLimits,
    FlightLog,
    FlightLogError,
    Issue,
    bounded_reasons,
    check_coherence,
    parse_metadata,
    read_flightlog,
    read_parquet_decimated,
    valid_id,
)
from server.models import Aircraft, ApiKey, Flight, Job, JobKind, upload_key_of, utcnow
from server.services.fleet import installed_serials
from server.services.storage import check_rejected_quota
from server.vocabulary import FlightStatus

__all__ = ["ingest_flight", "upload_key", "LostRace", "after_lost_race", "get_flight",
           "delete_rejected",
           "flight_codes", "list_flights", "decode_flight", "decimated_signals",
           "flight_signals", "signals_json", "ANALYSIS_JOB"]

ANALYSIS_JOB = JobKind.ANALYZE_FLIGHT


def _clean_id(value: Any) -> str | None:
    if value is None:
        return None
    text = str(value)[:64]
    return text if valid_id(text) else None


def upload_key(*, sha256: str, kind: str, form_metadata: Mapping[str, str]) -> str:
    """What makes two uploads the same one: the bytes, their kind and, for CSV/MAT, the metadata
    sent beside them (parsed and written back when it parses, so that ``1.5`` and ``1.50`` are
    the same block hours). Parquet carries its metadata inside the bytes; form fields beside it
    are not read. Migration 0005 keeps a frozen copy of this formula for existing rows."""
    return upload_key_of(kind, sha256,
                         {} if kind == "parquet" else _canonical_metadata(form_metadata))


def _canonical_metadata(form_metadata: Mapping[str, str]) -> dict[str, str]:
    try:
        return parse_metadata(form_metadata).to_strings()
    except FlightLogError:  # incomplete (a MAT file may carry the rest) or malformed: as sent
        return {str(k): str(v) for k, v in form_metadata.items()}


def _accepted_upload(session: Session, key: str) -> Flight | None:
    return session.scalar(select(Flight).where(Flight.upload_key == key,
                                               Flight.status != FlightStatus.REJECTED))


def ingest_flight(*, session: Session, blobs: BlobStore, upload: SpooledUpload, kind: str,
                  form_metadata: dict[str, str], uploader: ApiKey,
                  limits: DecodeLimits = DEFAULT_DECODE_LIMITS,
                  rejected_quota: int | None = None) -> tuple[Flight, bool]:
    """Register an uploaded flight; return ``(flight, duplicate)``.

    Raises :class:`Conflict` when an accepted flight with the same (aircraft, flight) came from
    another upload, :class:`PayloadTooLarge` (nothing registered) when the file is past one of
    the decode ``limits``. A file that fails decoding or coherence is stored as ``rejected``
    with its reasons (bounded in number and size): the same upload rejected before answers
    with that row (``duplicate``, nothing added), a new one is kept only within the uploader's
    ``rejected_quota`` [B] (else :class:`~server.services.storage.RejectedQuotaExceeded`,
    nothing kept; None: no quota).
    """
    key = upload_key(sha256=upload.sha256, kind=kind, form_metadata=form_metadata)
    existing = _accepted_upload(session, key)
    if existing is not None:
        upload.discard()
        return existing, True

    log: FlightLog | None = None
    issues: list[Issue]
    try:
        log = read_flightlog(upload.read_bytes(), kind=kind, metadata=form_metadata,
                             limits=limits)
    except FlightLogError as exc:
        if exc.too_large:
            raise _too_large(exc, limits) from None
        issues = list(exc.issues)
    tail = log.metadata.aircraft if log else _clean_id(form_metadata.get("aircraft"))
    code = log.metadata.flight if log else _clean_id(form_metadata.get("flight"))
    aircraft_id = (session.scalar(select(Aircraft.id).where(Aircraft.tail == tail))
                   if tail else None)

    if aircraft_id is not None and code is not None:
        clash = session.scalar(select(Flight).where(
            Flight.aircraft_id == aircraft_id, Flight.flight_code == code,
            Flight.status != FlightStatus.REJECTED))
        if clash is not None:
            upload.discard()
            if clash.upload_key == key:
                # the same upload, committed by a concurrent one since the check above
                return clash, True
            raise Conflict(f"Flight '{code}' of '{tail}' was already uploaded with other content.",
                           code="flight_exists", details={"flight_id": clash.id})
    if log is not None:
        issues = check_coherence(log, fleet_serials=installed_serials(
            session=session, tail=log.metadata.aircraft))  # the tail, read from the log
    reasons = bounded_reasons((i.as_dict() for i in issues), limits)
    if issues:
        again = _rejected_again(session, blobs, upload, key, reasons, aircraft_id)
        if again is not None:
            return again, True
        if rejected_quota is not None:
            check_rejected_quota(session, key_id=uploader.id, size=upload.size,
                                 quota=rejected_quota, reasons=reasons)

    blob_path = blobs.commit(upload)
    meta = log.metadata if log else None
    flight = Flight(
        aircraft_id=aircraft_id,
        tail=tail,
        flight_code=code,
        status=FlightStatus.REJECTED if issues else FlightStatus.QUEUED,
        reasons=reasons,
        sha256=upload.sha256,
        upload_key=key,
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
        # A concurrent upload won the race: the same upload (idempotent) or the same flight id
        # (conflict); the caller ends this unit of work and asks again (after_lost_race).
        raise LostRace(tail, code, key) from None
    return flight, False


def _rejected_again(session: Session, blobs: BlobStore, upload: SpooledUpload, key: str,
                    reasons: list[dict[str, Any]], aircraft_id: int | None) -> Flight | None:
    """The latest rejected row of the same upload, now rejected again: its reasons and
    aircraft brought up to this evaluation, its stored copy checked (a damaged one replaced
    by these bytes, in place); no new row, no new file. None when there is no such row."""
    previous = session.scalar(select(Flight).where(
        Flight.upload_key == key, Flight.status == FlightStatus.REJECTED)
        .order_by(Flight.id.desc()).limit(1))
    if previous is None:
        return None
    blobs.commit(upload)
    previous.reasons, previous.aircraft_id, previous.updated_at = reasons, aircraft_id, utcnow()
    session.flush()
    return previous


def _too_large(exc: FlightLogError, limits: DecodeLimits) -> PayloadTooLarge:
    """A file past a decode limit is refused like an oversized body: not stored, not a row."""
    return PayloadTooLarge("The flight log is larger than this service decodes; nothing was "
                           "registered.", code="flight_too_large",
                           details={"reasons": bounded_reasons(
                               (i.as_dict() for i in exc.issues), limits)})


class LostRace(Conflict):
    """A concurrent upload registered the same upload or the same (aircraft, flight) first."""

    def __init__(self, tail: str | None, code: str | None, upload_key: str):
        super().__init__(f"Flight '{code}' of '{tail}' was uploaded concurrently with other "
                         "content.", code="flight_exists")
        self.upload_key = upload_key


def after_lost_race(*, session: Session, race: LostRace) -> Flight:
    """In a new unit of work after :class:`LostRace`: the accepted flight registered by the
    same upload (this one was idempotent), or the race's conflict raised."""
    same = _accepted_upload(session, race.upload_key)
    if same is None:
        raise race
    return same


def get_flight(*, session: Session, flight_id: int) -> Flight:
    flight = session.get(Flight, flight_id)
    if flight is None:
        raise NotFound(f"Flight {flight_id} does not exist.")
    return flight


def delete_rejected(*, session: Session, flight_id: int) -> str | None:
    """Delete a rejected flight (and its analysis job, when the worker rejected it): what
    frees its key's rejected-bytes quota. Returns the blob path to remove once the caller has
    committed (never a row without its bytes), or None when another row keeping its log
    still refers to the file. Conflict unless the flight is rejected."""
    flight = get_flight(session=session, flight_id=flight_id)
    if flight.status != FlightStatus.REJECTED:
        raise Conflict(f"Flight {flight_id} is {flight.status}: only a rejected flight is "
                       "deleted.", code="not_rejected", details={"status": flight.status})
    sha256, blob_path = flight.sha256, flight.blob_path
    session.execute(delete(Job).where(Job.flight_id == flight_id))
    session.delete(flight)
    session.flush()
    shared = session.scalar(select(Flight.id).where(Flight.sha256 == sha256,
                                                    Flight.raw_pruned_at.is_(None)).limit(1))
    return None if shared is not None else blob_path


def flight_codes(*, session: Session, flight_ids: list[int]) -> dict[int, str | None]:
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


def _raw_kept(flight: Flight) -> None:
    if flight.raw_pruned_at is not None:
        raise Gone(f"The raw log of flight {flight.id} was removed by the raw-log retention "
                   f"on {flight.raw_pruned_at.isoformat()}; its features and results are "
                   "kept.", code="raw_pruned")


def decode_flight(*, blobs: BlobStore, flight: Flight,
                  limits: DecodeLimits = DEFAULT_DECODE_LIMITS) -> FlightLog:
    _raw_kept(flight)
    try:
        return read_flightlog(blobs.read(flight.blob_path), kind=flight.content_kind,
                              metadata=flight.flight_metadata, limits=limits)
    except FlightLogError as exc:
        raise _undecodable(exc, limits) from None


def _undecodable(exc: FlightLogError, limits: DecodeLimits) -> Unprocessable:
    return Unprocessable("The stored file of this flight cannot be decoded.", code="undecodable",
                         details={"reasons": bounded_reasons((i.as_dict() for i in exc.issues),
                                                             limits)})


def flight_signals(*, blobs: BlobStore, flight: Flight, channels: list[str] | None,
                   max_points: int, limits: DecodeLimits = DEFAULT_DECODE_LIMITS
                   ) -> tuple[int, dict[str, np.ndarray]]:
    """``(step, arrays)`` of :func:`decimated_signals` for a stored flight. Parquet (the
    canonical encoding) is decimated while it is read, so a request holds a batch and the
    result, not the flight; CSV and MAT are decoded whole, within ``limits``."""
    _raw_kept(flight)
    if flight.content_kind != "parquet":
        log = decode_flight(blobs=blobs, flight=flight, limits=limits)
        return decimated_signals(log, channels, max_points)
    try:
        return read_parquet_decimated(blobs.read(flight.blob_path), channels, max_points, limits)
    except FlightLogError as exc:
        unknown = [i for i in exc.issues if i.code == "unknown_channel"]
        if unknown:
            raise NotFound(unknown[0].message, code="unknown_channel",
                           details=unknown[0].details) from None
        raise _undecodable(exc, limits) from None


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


def signals_json(flight_id: int, step: int, arrays: dict[str, np.ndarray]) -> bytes:
    """``SignalsRead`` as JSON bytes, encoded one channel at a time: a request holds one
    channel's Python floats, not every channel's as lists, a model and its dump (some 20 MB for
    29 channels of 5000 points). Non-finite values are ``null``, as pydantic writes them."""
    def values(a: np.ndarray) -> bytes:
        floats = a.astype(float)
        listed: list[float] = floats.tolist()
        out: Sequence[float | None] = listed
        if not np.isfinite(floats).all():
            out = [v if math.isfinite(v) else None for v in listed]
        return json.dumps(out, separators=(",", ":")).encode()

    head = json.dumps({"flight_id": flight_id, "decimation": step}, separators=(",", ":"))
    parts = [head[:-1].encode(), b',"t":', values(arrays["t"]), b',"channels":{']
    for i, (name, a) in enumerate((k, v) for k, v in arrays.items() if k != "t"):
        parts += [b"," if i else b"", json.dumps(name).encode(), b":", values(a)]
    return b"".join([*parts, b"}}"])
