"""The error responses of each operation in the OpenAPI schema, all in the one error shape
``{"error": {"code", "message", "details"}}`` (``server.errors``).

Most follow from the operation itself (:func:`document_errors`): 401 and 429 (too many failed
authentications, ``server.ratelimit``) where a key is needed, 403
on a write (a role below the route's, or the session cookie without its CSRF token), 404 with a
path parameter, 400, 408 and 413 with a request body (unreadable, stalled, over the limit),
422 where anything is validated. The rest (a 409, a 403 on a read, a 404 without path
parameter) are declared on the route with :func:`errors`.
``tests/api/test_request_hardening.py`` checks the schema against what the operations answer.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from fastapi import FastAPI

__all__ = ["errors", "document_errors", "ERROR_SCHEMA"]

DESCRIPTIONS = {
    400: "The body could not be read (for JSON: not UTF-8), or a multipart field is missing.",
    401: "No API key, or the key is unknown or revoked.",
    403: "The key's role may not do this, or a write with the session cookie came without its "
         "CSRF token or from another origin.",
    404: "No such resource.",
    408: "The request body stalled (nothing arrived for the body idle timeout).",
    409: "The request conflicts with the current state.",
    410: "The flight's raw log was removed by the raw-log retention (its results are kept).",
    413: "The request body exceeds the size limit.",
    422: "The request is not valid.",
    429: "Too many failed authentications with this key, or (for a key that is not right) "
         "from this client address; try again after Retry-After seconds.",
    503: "Too many of these requests at once (`busy`); try again after Retry-After seconds.",
}
WRITE_METHODS = {"post", "put", "patch", "delete"}
ERROR_SCHEMA: dict[str, Any] = {
    "title": "Error",
    "type": "object",
    "required": ["error"],
    "properties": {"error": {
        "type": "object",
        "required": ["code", "message", "details"],
        "properties": {"code": {"type": "string"}, "message": {"type": "string"},
                       "details": {"type": "object"}},
    }},
}
_ERROR_CONTENT = {"application/json": {"schema": {"$ref": "#/components/schemas/Error"}}}


def errors(*codes: int) -> dict[int | str, dict[str, Any]]:
    """``responses=`` for a route: the errors it answers beyond those :func:`document_errors`
    infers."""
    return {code: {"description": DESCRIPTIONS[code]} for code in codes}


def document_errors(app: FastAPI) -> None:
    """Make ``app.openapi()`` list each operation's error responses."""
    generate: Callable[[], dict[str, Any]] = app.openapi

    def openapi() -> dict[str, Any]:
        if app.openapi_schema is None:
            schema = generate()  # FastAPI's, cached in app.openapi_schema
            for path, item in schema.get("paths", {}).items():
                for method, operation in item.items():
                    _add_inferred(path, method, operation)
            _use_error_schema(schema)
        return app.openapi_schema  # type: ignore[return-value]

    app.openapi = openapi  # type: ignore[method-assign]


def _add_inferred(path: str, method: str, operation: dict[str, Any]) -> None:
    codes: set[int] = set()
    if operation.get("security"):
        codes.update((401, 429))
        if method in WRITE_METHODS:
            codes.add(403)
    if "{" in path:
        codes.add(404)
    if "requestBody" in operation:
        codes.update((400, 408, 413))
    if operation.get("parameters") or "requestBody" in operation:
        codes.add(422)
    responses = operation.setdefault("responses", {})
    for code in sorted(codes):
        responses.setdefault(str(code), {"description": DESCRIPTIONS[code]})


def _use_error_schema(schema: dict[str, Any]) -> None:
    """Every 4xx/5xx in our error shape (FastAPI's default 422 describes another one)."""
    for item in schema.get("paths", {}).values():
        for operation in item.values():
            for status, response in operation.get("responses", {}).items():
                if str(status)[0] in "45":
                    response["content"] = _ERROR_CONTENT
    components = schema.setdefault("components", {}).setdefault("schemas", {})
    components.pop("HTTPValidationError", None)
    components.pop("ValidationError", None)
    components["Error"] = ERROR_SCHEMA
