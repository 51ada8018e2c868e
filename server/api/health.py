"""Liveness (the process answers) and readiness (the database answers, schema at head, and the
flight-log store answers)."""

from __future__ import annotations

import logging

from fastapi import APIRouter, Request
from fastapi.responses import JSONResponse

from server.blobstore import BlobStore, BlobStoreUnreachable
from server.db import DatabaseUnavailable, ping, unavailable_on_error
from server.errors import error_body
from server.migrate import current_revision, head_revision

router = APIRouter(prefix="/health", tags=["health"])
log = logging.getLogger("hmsm.health")


@router.get("/live", summary="Liveness: the process is up")
def live() -> dict[str, str]:
    return {"status": "ok"}


@router.get("/ready", summary="Readiness: the database answers and its schema is current, and "
            "the flight-log store answers")
def ready(request: Request) -> JSONResponse:
    engine = request.app.state.engine
    try:
        ping(engine)
        with unavailable_on_error():
            revision = current_revision(engine)
    except DatabaseUnavailable:
        return JSONResponse(error_body("database_unavailable", "The database does not answer."),
                            status_code=503)
    if revision != head_revision():
        return JSONResponse(error_body("schema_behind", "The database schema is not current; run "
                                       "`hmsm db upgrade`.", {"revision": revision}),
                            status_code=503)
    blobs: BlobStore = request.app.state.blobs
    try:
        blobs.ping()
    except OSError as exc:
        # uploads and log reads fail now (503, or 507 for a directory): not ready. The error
        # goes to the log only, as it may name the store's address
        log.warning("readiness: the flight-log store %s: %s", blobs.describe(), exc)
        unreachable = isinstance(exc, BlobStoreUnreachable)
        return JSONResponse(error_body(
            "storage_unreachable" if unreachable else "storage_unavailable",
            f"The flight-log store ({blobs.describe()}) "
            + ("does not answer." if unreachable else "refuses requests."),
            {"database": "ok", "blob_store": blobs.describe()}), status_code=503)
    return JSONResponse({"status": "ok", "database": "ok", "schema_revision": revision,
                         "blob_store": "ok"})
