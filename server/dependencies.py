"""Request dependencies shared by the API routers and the dashboard routes: the settings,
the blob store, one database session per request (rolled back unless committed), and the
request's own origin (what a browser's ``Origin`` header must equal)."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Annotated

from fastapi import Depends, Request
from sqlalchemy.orm import Session

from server.blobstore import BlobStore
from server.config import Settings

__all__ = ["SessionDep", "SettingsDep", "BlobsDep", "get_settings", "get_blobs", "get_session",
           "own_origin"]


def get_settings(request: Request) -> Settings:
    return request.app.state.settings


def get_blobs(request: Request) -> BlobStore:
    return request.app.state.blobs


def get_session(request: Request) -> Iterator[Session]:
    session = request.app.state.session_factory()
    try:
        yield session
    finally:
        session.rollback()
        session.close()


def own_origin(request: Request) -> str:
    return f"{request.url.scheme}://{request.url.netloc}"


SettingsDep = Annotated[Settings, Depends(get_settings)]
BlobsDep = Annotated[BlobStore, Depends(get_blobs)]
SessionDep = Annotated[Session, Depends(get_session)]
