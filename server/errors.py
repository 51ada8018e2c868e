"""Domain errors and the single JSON error shape ``{"error": {"code", "message", "details"}}``."""

from __future__ import annotations

import logging
import re
from typing import Any

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from sqlalchemy.exc import DataError, DBAPIError, OperationalError
from starlette.exceptions import HTTPException as StarletteHTTPException

from server.blobstore import BlobStoreUnreachable

log = logging.getLogger("hmsm.api")

__all__ = [
    "DomainError",
    "NotFound",
    "Conflict",
    "Unauthorized",
    "Forbidden",
    "PayloadTooLarge",
    "UnsupportedMediaType",
    "Unprocessable",
    "BadRequest",
    "ServiceUnavailable",
    "StorageUnavailable",
    "BodyOverLimit",
    "BodyTimeout",
    "error_body",
    "install_error_handlers",
]


class DomainError(Exception):
    status_code = 400
    code = "bad_request"

    def __init__(self, message: str, *, code: str | None = None,
                 details: dict[str, Any] | None = None, headers: dict[str, str] | None = None):
        super().__init__(message)
        self.message = message
        self.code = code or self.code
        self.details = details or {}
        self.headers = headers


class BadRequest(DomainError):
    status_code, code = 400, "bad_request"


class Unauthorized(DomainError):
    status_code, code = 401, "unauthorized"


class Forbidden(DomainError):
    status_code, code = 403, "forbidden"


class NotFound(DomainError):
    status_code, code = 404, "not_found"


class Conflict(DomainError):
    status_code, code = 409, "conflict"


class Gone(DomainError):
    status_code, code = 410, "gone"


class PayloadTooLarge(DomainError):
    status_code, code = 413, "payload_too_large"


class UnsupportedMediaType(DomainError):
    status_code, code = 415, "unsupported_media_type"


class Unprocessable(DomainError):
    status_code, code = 422, "unprocessable"


class ServiceUnavailable(DomainError):
    status_code, code = 503, "service_unavailable"


class StorageUnavailable(DomainError):
    """The blob store cannot take the file (disk full, read-only, missing directory)."""

    status_code, code = 507, "storage_unavailable"


class BodyOverLimit(StarletteHTTPException):
    """The request body went over the limit while it was being read. An HTTPException rather
    than a :class:`DomainError` because FastAPI re-raises only those from its JSON body reader
    (any other exception there becomes a 400)."""

    def __init__(self, limit_bytes: int):
        super().__init__(413, f"The request body exceeds {limit_bytes} bytes.",
                         headers={"Connection": "close"})
        self.details = {"limit_bytes": limit_bytes}


class BodyTimeout(StarletteHTTPException):
    """The client sent none of the rest of its request body for too long (a slow client)."""

    def __init__(self, idle_s: float):
        super().__init__(408, f"No request body data arrived for {idle_s:g} s.",
                         headers={"Connection": "close"})
        self.details = {"idle_timeout_s": idle_s}


def error_body(code: str, message: str, details: dict[str, Any] | None = None) -> dict[str, Any]:
    return {"error": {"code": code, "message": message, "details": details or {}}}


_HTTP_CODES = {400: "bad_request", 401: "unauthorized", 403: "forbidden", 404: "not_found",
               405: "method_not_allowed", 408: "request_timeout", 409: "conflict",
               413: "payload_too_large", 415: "unsupported_media_type", 422: "validation_error",
               503: "service_unavailable"}


def _allowed_methods(request: Request) -> str:
    """Every method the API documents on the request's path ("" for the dashboard's pages,
    outside the schema: Starlette's header stays)."""
    methods: set[str] = set()
    for template, item in request.app.openapi().get("paths", {}).items():
        if re.fullmatch(re.sub(r"\\\{[^}]+\\\}", "[^/]+", re.escape(template)),
                        request.url.path):
            methods.update(m.upper() for m in item if m != "parameters")
    if "GET" in methods:
        methods.add("HEAD")
    return ", ".join(sorted(methods))


def install_error_handlers(app: FastAPI) -> None:
    @app.exception_handler(DomainError)
    async def _domain(_: Request, exc: DomainError) -> JSONResponse:
        return JSONResponse(error_body(exc.code, exc.message, exc.details),
                            status_code=exc.status_code, headers=exc.headers)

    @app.exception_handler(StarletteHTTPException)
    async def _http(request: Request, exc: StarletteHTTPException) -> JSONResponse:
        code = _HTTP_CODES.get(exc.status_code, "http_error")
        headers = getattr(exc, "headers", None)
        if exc.status_code == 405 and (allowed := _allowed_methods(request)):
            headers = {**(headers or {}), "Allow": allowed}  # not only the first route's
        return JSONResponse(error_body(code, str(exc.detail), getattr(exc, "details", None)),
                            status_code=exc.status_code, headers=headers)

    @app.exception_handler(RequestValidationError)
    async def _validation(_: Request, exc: RequestValidationError) -> JSONResponse:
        errors = [{"loc": list(e.get("loc", ())), "msg": e.get("msg", ""), "type": e.get("type")}
                  for e in exc.errors()]
        return JSONResponse(error_body("validation_error", "The request is not valid.",
                                       {"errors": errors}), status_code=422)

    @app.exception_handler(OperationalError)
    async def _db_down(_: Request, exc: OperationalError) -> JSONResponse:
        return JSONResponse(error_body("database_unavailable", "The database cannot be reached; "
                                       "try again shortly."), status_code=503,
                            headers={"Retry-After": "5"})

    @app.exception_handler(BlobStoreUnreachable)
    async def _store_down(request: Request, exc: BlobStoreUnreachable) -> JSONResponse:
        # the object store's outage, never the request's fault: nothing was registered
        log.error("blob store unreachable on %s %s: %s", request.method, request.url.path, exc)
        return JSONResponse(error_body("storage_unreachable", "The flight-log store does not "
                                       "answer now; nothing was registered. Try again "
                                       "shortly."), status_code=503,
                            headers={"Retry-After": "30"})

    @app.exception_handler(OverflowError)
    async def _overflow(request: Request, exc: OverflowError) -> JSONResponse:
        # a number beyond 64 bits that reached the SQLite driver past the schema's bounds
        # (server/schemas.py bounds ids, counts and offsets): the driver's words only logged
        log.warning("number out of range on %s %s: %s", request.method, request.url.path, exc)
        return JSONResponse(error_body("validation_error", "A number in the request is out of "
                                       "range."), status_code=422)

    @app.exception_handler(MemoryError)
    async def _out_of_memory(request: Request, exc: MemoryError) -> JSONResponse:
        # also pyarrow's ArrowMemoryError: the server's state, never a defect of the request
        log.error("out of memory on %s %s", request.method, request.url.path)
        return JSONResponse(error_body("insufficient_memory", "The server has not enough memory "
                                       "for this request now; nothing was registered. Try again "
                                       "later."), status_code=503, headers={"Retry-After": "30"})

    @app.exception_handler(DBAPIError)
    async def _db_error(_: Request, exc: DBAPIError) -> JSONResponse:
        if isinstance(exc, DataError):  # PostgreSQL: value out of range for the column type
            return JSONResponse(error_body("validation_error", "A value in the request is out "
                                           "of range for the database."), status_code=422)
        if exc.connection_invalidated:
            return JSONResponse(error_body("database_unavailable", "The database connection was "
                                           "lost; try again shortly."), status_code=503,
                                headers={"Retry-After": "5"})
        return JSONResponse(error_body("internal_error", "Unexpected database error."),
                            status_code=500)

    @app.exception_handler(Exception)
    async def _unexpected(request: Request, exc: Exception) -> JSONResponse:
        log.error("unhandled error on %s %s", request.method, request.url.path, exc_info=exc)
        return JSONResponse(error_body("internal_error", "Unexpected server error."),
                            status_code=500)
