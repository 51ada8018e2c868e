"""Dependencies of the API routers: the caller's key and role (bearer key or the dashboard's
session cookie), plus the shared settings, blob store and session (:mod:`server.dependencies`)."""

from __future__ import annotations

from typing import Annotated

from fastapi import Depends, Request
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer

from server.auth import ALLOWED, authenticate, may
from server.dependencies import BlobsDep, SessionDep, SettingsDep
from server.errors import Forbidden, Unauthorized
from server.models import ApiKey

__all__ = ["SessionDep", "SettingsDep", "BlobsDep", "Reader", "Uploader", "Operator", "Admin",
           "CurrentKey"]

_bearer = HTTPBearer(auto_error=False, description="API key: `Authorization: Bearer hmsm_...`")


def current_key(
    request: Request,
    session: SessionDep,
    credentials: Annotated[HTTPAuthorizationCredentials | None, Depends(_bearer)],
) -> ApiKey:
    token = credentials.credentials if credentials else request.cookies.get("hmsm_session")
    if not token:
        raise Unauthorized("An API key is required (Authorization: Bearer ...).",
                           headers={"WWW-Authenticate": "Bearer"})
    key = authenticate(session=session, plaintext=token)
    if key is None:
        raise Unauthorized("The API key is unknown or revoked.",
                           headers={"WWW-Authenticate": "Bearer"})
    return key


CurrentKey = Annotated[ApiKey, Depends(current_key)]


def _require(action: str):  # type: ignore[no-untyped-def]
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
