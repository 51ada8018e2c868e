"""Liveness (the process answers) and readiness (the database answers, schema at head)."""

from __future__ import annotations

from fastapi import APIRouter, Request
from fastapi.responses import JSONResponse

from server.db import DatabaseUnavailable, ping, unavailable_on_error
from server.errors import error_body
from server.migrate import current_revision, head_revision

router = APIRouter(prefix="/health", tags=["health"])


@router.get("/live", summary="Liveness: the process is up")
def live() -> dict[str, str]:
    return {"status": "ok"}


@router.get("/ready", summary="Readiness: the database answers and its schema is current")
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
    return JSONResponse({"status": "ok", "database": "ok", "schema_revision": revision})
