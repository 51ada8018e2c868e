"""Flight-log upload, listing, status and decimated signals.

``POST /flights`` takes either a multipart form (field ``file`` plus metadata fields, needed for
CSV and MAT) or a raw body of type ``application/vnd.apache.parquet``. The body is streamed to
disk with a running size check, never held whole in memory beyond the configured limit.
"""

from __future__ import annotations

import logging
from collections.abc import AsyncIterator
from typing import Annotated, Any

from fastapi import APIRouter, Query, Request
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import JSONResponse, Response
from starlette.datastructures import UploadFile

from server.api.deps import Admin, BlobsDep, Reader, SessionDep, SettingsDep, Uploader
from server.api.openapi import errors
from server.api.presenters import flight_read
from server.auth import keys_by_id
from server.blobstore import BlobStore, BlobStoreUnreachable, BlobTooLarge, SpooledUpload
from server.config import Settings
from server.errors import (
    BadRequest,
    PayloadTooLarge,
    StorageUnavailable,
    UnsupportedMediaType,
    error_body,
)
from server.flightlog import METADATA_FIELDS
from server.models import ApiKey, Flight
from server.schemas import (
    FlightAccepted,
    FlightRead,
    FlightStatusFilter,
    IdPath,
    Offset,
    Page,
    SignalsRead,
)
from server.services import analysis as analysis_service
from server.services import flights as service
from server.vocabulary import FlightStatus

router = APIRouter(prefix="/flights", tags=["flights"])
log = logging.getLogger("hmsm.api")

PARQUET_TYPES = {"application/vnd.apache.parquet", "application/x-parquet"}
_UPLOAD_DOC = {
    "requestBody": {
        "required": True,
        "content": {
            "application/vnd.apache.parquet": {"schema": {"type": "string", "format": "binary"}},
            "multipart/form-data": {"schema": {
                "type": "object", "required": ["file"],
                "properties": {"file": {"type": "string", "format": "binary"},
                               **{k: {"type": "string"} for k in METADATA_FIELDS}}}},
        },
    },
    "responses": {
        "200": {"description": "The same upload as an accepted flight (idempotent): the same "
                "bytes and, for CSV/MAT, the same metadata fields."},
        "409": {"description": "Another file exists for this (aircraft, flight)."},
        "413": {"description": "Body over the size limit, or the file past a decode limit "
                "(`flight_too_large`, reasons name the limit); nothing was registered."},
        "415": {"description": "Unsupported content type or file kind."},
        "422": {"description": "Failed coherence checks; stored as rejected with reasons (the "
                "same upload sent again is evaluated again: rejected again, it answers with the "
                "same row, `duplicate` true, and nothing more is kept)."},
        "503": {"description": "The object store does not answer (`storage_unreachable`); "
                "nothing was registered: send it again after Retry-After."},
        "507": {"description": "The blob store cannot take the file (`storage_unavailable`), "
                "or the file failed the coherence checks and keeping it would take the key past "
                "HMSM_REJECTED_BYTES_PER_KEY (`rejected_quota_exceeded`, reasons in the "
                "details); nothing was registered."},
    },
}


def _kind_of_file(upload: UploadFile) -> str:
    name = (upload.filename or "").lower()
    if name.endswith(".parquet"):
        return "parquet"
    if name.endswith((".csv", ".csv.gz")):
        return "csv"
    if name.endswith(".mat"):
        return "mat"
    ctype = (upload.content_type or "").split(";")[0].strip().lower()
    if ctype in PARQUET_TYPES:
        return "parquet"
    if ctype in ("text/csv", "application/gzip"):
        return "csv"
    raise UnsupportedMediaType("The file must be .parquet, .csv, .csv.gz or .mat.",
                               details={"filename": upload.filename, "content_type": ctype})


async def _chunks_of(upload: UploadFile) -> AsyncIterator[bytes]:
    while chunk := await upload.read(1 << 20):
        yield chunk


@router.post("", status_code=202, response_model=FlightAccepted, openapi_extra=_UPLOAD_DOC,
             summary="Upload a flight log (uploader)")
async def upload(request: Request, session: SessionDep, blobs: BlobsDep, settings: SettingsDep,
                 key: Uploader) -> Any:
    ctype = request.headers.get("content-type", "").split(";")[0].strip().lower()
    form_metadata: dict[str, str] = {}
    try:
        if ctype in PARQUET_TYPES:
            kind = "parquet"
            spooled = await blobs.spool(request.stream(), max_bytes=settings.max_upload_bytes)
        elif ctype == "multipart/form-data":
            form = await request.form(max_files=1, max_fields=len(METADATA_FIELDS) + 1)
            file = form.get("file")
            if not isinstance(file, UploadFile):
                raise BadRequest("The multipart form needs a file field named 'file'.",
                                 code="missing_file")
            kind = _kind_of_file(file)
            form_metadata = {k: str(v) for k, v in form.items()
                             if k in METADATA_FIELDS and isinstance(v, str)}
            spooled = await blobs.spool(_chunks_of(file), max_bytes=settings.max_upload_bytes)
            await form.close()
        else:
            raise UnsupportedMediaType(
                "Send application/vnd.apache.parquet or multipart/form-data.",
                details={"content_type": ctype or None})
    except BlobTooLarge:
        raise PayloadTooLarge(f"The upload exceeds {settings.max_upload_bytes} bytes.",
                              details={"limit_bytes": settings.max_upload_bytes}) from None
    except OSError as exc:
        raise _storage_unavailable(exc) from None

    outcome = "refused"  # unless ingest says otherwise: conflict, too large, over quota...
    try:
        flight, duplicate = await run_in_threadpool(_ingest, session, blobs, spooled, kind,
                                                    form_metadata, key, settings)
        outcome = ("rejected" if flight.status == FlightStatus.REJECTED
                   else "duplicate" if duplicate else "accepted")
    except BlobStoreUnreachable:
        raise  # 503 (server.errors): the store is away, not full
    except OSError as exc:
        # The blob store failed before the flight row was flushed: nothing was registered.
        raise _storage_unavailable(exc) from None
    finally:
        request.app.state.metrics.observe_upload(outcome, spooled.size)
    body = FlightAccepted(id=flight.id, status=flight.status,
                          status_url=f"/api/v1/flights/{flight.id}", duplicate=duplicate)
    if flight.status == FlightStatus.REJECTED:
        return JSONResponse(error_body("incoherent_flight", "The flight log failed coherence "
                                       "checks and was stored as rejected.",
                                       {**body.model_dump(), "reasons": flight.reasons}),
                            status_code=422, headers={"Location": body.status_url})
    return JSONResponse(body.model_dump(), status_code=200 if duplicate else 202,
                        headers={"Location": body.status_url})


def _storage_unavailable(exc: OSError) -> StorageUnavailable:
    log.error("blob store write failed: %s", exc)
    return StorageUnavailable("The flight store cannot take the file now (disk full or not "
                              "writable); nothing was registered. Try again later.",
                              details={"errno": exc.errno}, headers={"Retry-After": "60"})


def _ingest(session: SessionDep, blobs: BlobStore, spooled: SpooledUpload, kind: str,
            form_metadata: dict[str, str], key: ApiKey, settings: Settings
            ) -> tuple[Flight, bool]:
    try:
        flight, duplicate = service.ingest_flight(
            session=session, blobs=blobs, upload=spooled, kind=kind,
            form_metadata=form_metadata, uploader=key, limits=settings.decode_limits,
            rejected_quota=settings.rejected_bytes_per_key)
        session.commit()
        return flight, duplicate
    except service.LostRace as race:
        session.rollback()
        return service.after_lost_race(session=session, race=race), True
    finally:
        spooled.discard()


@router.get("", response_model=Page[FlightRead], summary="List flights")
def list_(session: SessionDep, _: Reader,
          aircraft: str | None = None,
          status: FlightStatusFilter = None,
          limit: Annotated[int, Query(ge=1, le=500)] = 50,
          offset: Offset = 0) -> Page[FlightRead]:
    rows, total = service.list_flights(session=session, tail=aircraft, status=status,
                                       limit=limit, offset=offset)
    keys = keys_by_id(session=session, key_ids=[r.uploader_key_id for r in rows])
    return Page(items=[flight_read(r, _uploader(keys, r)) for r in rows], total=total,
                limit=limit, offset=offset)


def _uploader(keys: dict[int, ApiKey], row: Flight) -> ApiKey | None:
    return None if row.uploader_key_id is None else keys.get(row.uploader_key_id)


def _with_uploader(session: SessionDep, row: Flight) -> FlightRead:
    return flight_read(row, _uploader(keys_by_id(session=session, key_ids=[row.uploader_key_id]),
                                      row))


@router.get("/{flight_id}", response_model=FlightRead, summary="One flight: status and reasons")
def get(flight_id: IdPath, session: SessionDep, _: Reader) -> FlightRead:
    row = service.get_flight(session=session, flight_id=flight_id)
    return _with_uploader(session, row)


@router.get("/{flight_id}/signals", response_model=SignalsRead, responses=errors(410, 503),
            summary="Signals of a flight, decimated for plotting")
async def signals(flight_id: IdPath, request: Request, session: SessionDep, blobs: BlobsDep,
                  settings: SettingsDep, _: Reader,
                  channels: Annotated[str | None, Query(description="Comma-separated channel "
                                                        "names; default all.",
                                                        max_length=2000)] = None,
                  max_points: Annotated[int | None, Query(ge=10)] = None) -> Response:
    """Read on the app's signal pool (`HMSM_SIGNALS_CONCURRENCY` at once, the next
    `HMSM_SIGNALS_WAITING` wait their turn, any more are answered 503 `busy`)."""
    wanted = [c.strip() for c in channels.split(",") if c.strip()] if channels else None
    points = min(max_points or settings.signals_max_points, settings.signals_max_points)

    def read() -> bytes:
        row = service.get_flight(session=session, flight_id=flight_id)
        step, data = service.flight_signals(blobs=blobs, flight=row, channels=wanted,
                                            max_points=points, limits=settings.decode_limits)
        return service.signals_json(row.id, step, data)

    return Response(await request.app.state.signal_reads.run(read),
                    media_type="application/json")


@router.delete("/{flight_id}", status_code=204, responses=errors(409),
               summary="Delete a rejected flight and its file (admin)")
def delete_rejected(flight_id: IdPath, session: SessionDep, blobs: BlobsDep, _: Admin) -> Response:
    """Only a rejected flight (409 `not_rejected` otherwise): its row goes, and its file
    unless another kept flight shares it; its uploader's rejected-bytes quota is freed."""
    orphan = service.delete_rejected(session=session, flight_id=flight_id)
    session.commit()
    if orphan is not None:
        try:
            blobs.delete(orphan)
        except OSError as exc:  # the row is gone either way; a worker's start sweeps the bytes
            log.warning("could not delete the blob of rejected flight %s: %s", flight_id, exc)
    return Response(status_code=204)


@router.post("/{flight_id}/retry", status_code=202, response_model=FlightRead,
             responses=errors(409), summary="Analyse a failed flight again (admin)")
def retry(flight_id: IdPath, session: SessionDep, _: Admin) -> FlightRead:
    """Queue the analysis of a flight whose analysis was given up (status ``failed``) again,
    with a fresh count of attempts; 409 ``not_failed`` for a flight in any other state."""
    row = analysis_service.retry_failed(session=session, flight_id=flight_id)
    session.commit()
    return _with_uploader(session, row)
