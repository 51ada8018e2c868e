"""API documentation: Swagger UI at ``/docs``, ReDoc at ``/redoc``, the schema at
``/openapi.json``.

Like every request but the health checks (docs/SECURITY.md), they need a key: a Bearer key or
the dashboard's session cookie. A browser without one is sent to the sign-in page and back,
the schema's too (a page asked for by a browser's address bar); any other client asking for the
schema without a key gets 401 with ``WWW-Authenticate: Bearer``, which tells a tool what is
missing (a redirect to an HTML form would not). Swagger UI
and ReDoc come from the installed ``fastapi-offline`` package (mounted at ``DOCS_ASSETS_URL`` by
the app factory), never from a CDN, and the pages carry no inline script, so the dashboard's CSP
holds on them: Swagger UI is started by ``/static/swagger-init.js``, which also sends the
session's CSRF token with the writes tried from the page.
"""

from __future__ import annotations

from html import escape
from pathlib import Path
from typing import Annotated
from urllib.parse import quote

import fastapi_offline
from fastapi import APIRouter, Depends, Request
from fastapi.responses import HTMLResponse, JSONResponse, RedirectResponse, Response
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer

from server.api.deps import SessionDep, presented_key
from server.auth import authenticate, csrf_token
from server.errors import Unauthorized

__all__ = ["router", "DOCS_ASSETS_DIR", "DOCS_ASSETS_URL", "OPENAPI_URL"]

DOCS_ASSETS_DIR = Path(fastapi_offline.__file__).resolve().parent / "static"
DOCS_ASSETS_URL = "/docs-assets"
OPENAPI_URL = "/openapi.json"
_NO_STORE = {"Cache-Control": "no-store"}

router = APIRouter(include_in_schema=False)
_bearer = HTTPBearer(auto_error=False)

_SWAGGER = """<!doctype html>
<html lang="en">
<head>
  <meta charset="utf-8">
  <meta name="viewport" content="width=device-width, initial-scale=1">
  <title>{title} - Swagger UI</title>
  <link rel="icon" href="{assets}/favicon.png">
  <link rel="stylesheet" href="{assets}/swagger-ui.css">
  <meta name="hmsm-csrf" content="{csrf}">
</head>
<body>
  <div id="swagger-ui" data-openapi-url="{openapi}"></div>
  <script src="{assets}/swagger-ui-bundle.js"></script>
  <script src="/static/swagger-init.js"></script>
</body>
</html>
"""

_REDOC = """<!doctype html>
<html lang="en">
<head>
  <meta charset="utf-8">
  <meta name="viewport" content="width=device-width, initial-scale=1">
  <title>{title} - ReDoc</title>
  <link rel="icon" href="{assets}/favicon.png">
</head>
<body>
  <redoc spec-url="{openapi}" disable-search="true"></redoc>
  <script src="{assets}/redoc.standalone.js"></script>
</body>
</html>
"""


def _page(request: Request, session: SessionDep,
          credentials: HTTPAuthorizationCredentials | None, template: str) -> Response:
    token, from_cookie = presented_key(request, credentials)
    if not token or authenticate(session=session, plaintext=token) is None:
        return RedirectResponse(f"/signin?next={quote(request.url.path, safe='')}",
                                status_code=303)
    html = template.format(title=escape(request.app.title), assets=DOCS_ASSETS_URL,
                           openapi=OPENAPI_URL, csrf=csrf_token(token) if from_cookie else "")
    return HTMLResponse(html, headers=_NO_STORE)


@router.get("/docs")
def swagger_ui(request: Request, session: SessionDep,
               credentials: Annotated[HTTPAuthorizationCredentials | None, Depends(_bearer)]
               ) -> Response:
    return _page(request, session, credentials, _SWAGGER)


@router.get("/redoc")
def redoc(request: Request, session: SessionDep,
          credentials: Annotated[HTTPAuthorizationCredentials | None, Depends(_bearer)]
          ) -> Response:
    return _page(request, session, credentials, _REDOC)


@router.get(OPENAPI_URL)
def openapi(request: Request, session: SessionDep,
            credentials: Annotated[HTTPAuthorizationCredentials | None, Depends(_bearer)]
            ) -> Response:
    token, _ = presented_key(request, credentials)
    if token and authenticate(session=session, plaintext=token) is not None:
        return JSONResponse(request.app.openapi())
    if request.headers.get("sec-fetch-mode") == "navigate":  # a browser's address bar or link
        return RedirectResponse(f"/signin?next={quote(OPENAPI_URL, safe='')}", status_code=303)
    raise Unauthorized("An API key is required (Authorization: Bearer ...), or a signed-in "
                       "dashboard session.", headers={"WWW-Authenticate": "Bearer"})
