"""Dependencies of the API routers: the caller's key and role (bearer key or the dashboard's
session cookie), plus the shared settings, blob store and session (:mod:`server.dependencies`).

A write authenticated by the session cookie needs the session's CSRF token in the
``X-CSRF-Token`` header and no foreign ``Origin`` (``server.auth.session_write_refusal``, the
rule of the dashboard's forms); Bearer-key requests are not touched by it, since no browser
adds an ``Authorization`` header to a cross-site request by itself."""

from __future__ import annotations

import hmac
from collections.abc import Callable
from typing import Annotated

from fastapi import Depends, Request
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer

from server.auth import (
    ALLOWED,
    CSRF_HEADER,
    SAFE_METHODS,
    SESSION_COOKIE,
    authenticate,
    may,
    session_write_refusal,
)
from server.dependencies import BlobsDep, SessionDep, SettingsDep, own_origin
from server.errors import Forbidden, Unauthorized
from server.models import ApiKey

__all__ = ["SessionDep", "SettingsDep", "BlobsDep", "Reader", "Uploader", "Operator",
           "Maintainer", "Admin", "CurrentKey", "presented_key", "MetricsReader"]

_bearer = HTTPBearer(auto_error=False, description="API key: `Authorization: Bearer hmsm_...`")


def presented_key(request: Request, credentials: HTTPAuthorizationCredentials | None
                  ) -> tuple[str | None, bool]:
    """The key the request presents and whether it came in the session cookie."""
    if credentials:
        return credentials.credentials, False
    return request.cookies.get(SESSION_COOKIE), True


def current_key(
    request: Request,
    session: SessionDep,
    credentials: Annotated[HTTPAuthorizationCredentials | None, Depends(_bearer)],
) -> ApiKey:
    token, from_cookie = presented_key(request, credentials)
    if not token:
        raise Unauthorized("An API key is required (Authorization: Bearer ...).",
                           headers={"WWW-Authenticate": "Bearer"})
    key = authenticate(session=session, plaintext=token)
    if key is None:
        raise Unauthorized("The API key is unknown or revoked.",
                           headers={"WWW-Authenticate": "Bearer"})
    if from_cookie and request.method not in SAFE_METHODS:
        _refuse_forged_write(request, token)
    return key


def _refuse_forged_write(request: Request, cookie: str) -> None:
    refusal = session_write_refusal(session_cookie=cookie,
                                    presented_token=request.headers.get(CSRF_HEADER),
                                    origin=request.headers.get("origin"),
                                    own_origin=own_origin(request))
    if refusal == "cross_origin":
        raise Forbidden("Cross-origin write with the session cookie refused.", code=refusal)
    if refusal is not None:
        raise Forbidden(f"A write with the session cookie needs the {CSRF_HEADER} header "
                        "(the dashboard's token); API clients use a Bearer key.", code=refusal)


CurrentKey = Annotated[ApiKey, Depends(current_key)]


def _require(action: str) -> Callable[[ApiKey], ApiKey]:
    def dependency(key: CurrentKey) -> ApiKey:
        if not may(key.role, action):
            raise Forbidden(f"Role '{key.role}' may not do this; it needs one of: "
                            + ", ".join(sorted(ALLOWED[action])) + ".")
        return key

    return dependency


Reader = Annotated[ApiKey, Depends(_require("read"))]
Uploader = Annotated[ApiKey, Depends(_require("upload"))]
Operator = Annotated[ApiKey, Depends(_require("operate"))]
Admin = Annotated[ApiKey, Depends(_require("admin"))]
#: maintenance actions (replace, inspect, defer): maintainer or admin
Maintainer = Annotated[ApiKey, Depends(_require("maintain"))]


def metrics_reader(
    session: SessionDep,
    settings: SettingsDep,
    credentials: Annotated[HTTPAuthorizationCredentials | None, Depends(_bearer)],
) -> None:
    """Who may read /metrics: the bearer of ``HMSM_METRICS_TOKEN`` (a scraper's credential
    that can do nothing else) or of an admin key; Bearer only, never the session cookie.
    A wrong token is a failed authentication (401), counted by the address's budget."""
    if credentials is None or not credentials.credentials:
        raise Unauthorized("/metrics needs Authorization: Bearer <metrics token or admin key>.",
                           headers={"WWW-Authenticate": "Bearer"})
    presented = credentials.credentials
    token = settings.metrics_token
    if token is not None and hmac.compare_digest(presented.encode(),
                                                 token.get_secret_value().encode()):
        return
    key = authenticate(session=session, plaintext=presented)
    if key is None:
        raise Unauthorized("The metrics token or API key is wrong or revoked.",
                           headers={"WWW-Authenticate": "Bearer"})
    if not may(key.role, "admin"):
        raise Forbidden(f"Role '{key.role}' may not read /metrics; it needs the metrics token "
                        "or an admin key.")


MetricsReader = Annotated[None, Depends(metrics_reader)]
