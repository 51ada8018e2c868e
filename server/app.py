"""Application factory: ``create_app(settings)`` builds everything; nothing happens at import."""

from __future__ import annotations

import asyncio
import time
from collections.abc import Callable

from fastapi import FastAPI
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from server.api import (
    actuators,
    aircraft,
    docs,
    flights,
    health,
    health_records,
    jobs,
    keys,
    metrics,
    models_api,
    storage,
    test_station,
)
from server.api.openapi import document_errors
from server.blobstore_factory import open_blob_store
from server.boundedpool import BoundedPool
from server.config import Settings
from server.db import make_engine, make_session_factory
from server.errors import BodyOverLimit, BodyTimeout, install_error_handlers
from server.metrics import RequestMetricsMiddleware, RouteTemplates, ServiceMetrics
from server.migrate import ensure_schema
from server.ratelimit import AuthFailureLimitMiddleware

__all__ = ["create_app"]

API_PREFIX = "/api/v1"
# Multipart framing and metadata fields on top of the file itself.
_MULTIPART_OVERHEAD_BYTES = 64 * 1024


class BodyLimitMiddleware:
    """Refuse request bodies over the limit: early by Content-Length, else while streaming."""

    def __init__(self, app: ASGIApp, max_bytes: int):
        self.app = app
        self.max_bytes = max_bytes + _MULTIPART_OVERHEAD_BYTES

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        headers = dict(scope.get("headers") or [])
        declared = headers.get(b"content-length")
        if declared is not None and declared.isdigit() and int(declared) > self.max_bytes:
            from fastapi.responses import JSONResponse

            from server.errors import error_body

            response = JSONResponse(error_body("payload_too_large", "The request body exceeds "
                                               f"{self.max_bytes} bytes.",
                                               {"limit_bytes": self.max_bytes}), status_code=413,
                                    headers={"Connection": "close"})
            await response(scope, receive, send)
            return
        seen = 0

        async def limited_receive() -> Message:
            nonlocal seen
            message = await receive()
            if message["type"] == "http.request":
                seen += len(message.get("body", b""))
                if seen > self.max_bytes:
                    raise BodyOverLimit(self.max_bytes)
            return message

        await self.app(scope, limited_receive, send)


class BodyIdleTimeoutMiddleware:
    """Cut a request whose body stalls for ``idle_s`` (408): uvicorn waits for a slow body
    forever. Only while the body is incomplete: a finished request's ``receive`` (which waits
    for the disconnect, e.g. under the event stream) is left alone."""

    def __init__(self, app: ASGIApp, idle_s: float):
        self.app = app
        self.idle_s = idle_s

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        body_complete = False

        async def paced_receive() -> Message:
            nonlocal body_complete
            if body_complete:
                return await receive()
            try:
                message = await asyncio.wait_for(receive(), self.idle_s)
            except TimeoutError:
                raise BodyTimeout(self.idle_s) from None
            if message["type"] != "http.request" or not message.get("more_body", False):
                body_complete = True
            return message

        await self.app(scope, paced_receive, send)


class SecurityHeadersMiddleware:
    """Conservative headers on every response; the CSP allows only our own origin, on the
    dashboard and the API documentation pages alike (their assets are served by us)."""

    HEADERS = [
        (b"x-content-type-options", b"nosniff"),
        (b"x-frame-options", b"DENY"),
        (b"referrer-policy", b"no-referrer"),
        (b"content-security-policy",
         b"default-src 'self'; img-src 'self' data:; style-src 'self' 'unsafe-inline'; "
         b"script-src 'self'; frame-ancestors 'none'"),
    ]

    def __init__(self, app: ASGIApp):
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return

        async def send_with_headers(message: Message) -> None:
            if message["type"] == "http.response.start":
                present = {k.lower() for k, _ in message.get("headers", [])}
                extra = [(k, v) for k, v in self.HEADERS if k not in present]
                message["headers"] = list(message.get("headers", [])) + extra
            await send(message)

        await self.app(scope, receive, send_with_headers)


def create_app(settings: Settings, *, auto_upgrade: bool | None = None,
               clock: Callable[[], float] = time.monotonic) -> FastAPI:
    """Build the HMSM app. The embedded SQLite default migrates itself; others must be current.
    ``clock``: the failed-authentication limit's time source [s] (a test drives it)."""
    settings.data_dir.mkdir(parents=True, exist_ok=True)
    engine = make_engine(settings.effective_database_url)
    ensure_schema(engine, settings.effective_database_url,
                  auto_upgrade=settings.is_sqlite if auto_upgrade is None else auto_upgrade)
    blobs = open_blob_store(settings)
    blobs.sweep_tmp()  # uploads of a process that was killed mid-way

    # /docs, /redoc and /openapi.json are server.api.docs's routes: local assets, a key needed
    app = FastAPI(title="EMA Health Management System (HMSM)", version="1",
                  description="Flight-log ingest, fault detection, classification and RUL "
                  "prognosis for electromechanical flight-control actuators.\n\nNumbers in "
                  "JSON bodies: an `integer` field takes a number without a fraction (`174` or "
                  "`174.0`, one JSON number), a `number` field any finite number; neither takes "
                  "`true` or a string such as `\"1.5\"` (422).",
                  docs_url=None, redoc_url=None, openapi_url=None)
    app.state.settings = settings
    app.state.engine = engine
    app.state.session_factory = make_session_factory(engine)
    app.state.blobs = blobs
    app.state.signal_reads = BoundedPool("signals", settings.signals_concurrency,
                                         settings.signals_waiting)
    app.state.metrics = ServiceMetrics(app.state.session_factory)
    install_error_handlers(app)
    document_errors(app)
    from server.web import events as web_events
    from server.web import routes as web_routes

    # each router with its prefix, also registered for the route label of /metrics
    routers = [(m.router, API_PREFIX) for m in (health, aircraft, actuators, health_records,
                                                 flights, jobs, models_api, keys, test_station,
                                                 storage, web_events)]
    routers += [(web_routes.router, ""),  # dashboard pages; "/" redirects to /fleet
                (docs.router, ""),
                (metrics.router, "")]  # /metrics: where Prometheus looks by default
    templates = RouteTemplates()
    for router, prefix in routers:
        app.include_router(router, prefix=prefix)
        templates.add_router(router, prefix)
    app.add_exception_handler(web_routes.SignInRequired, web_routes.signin_redirect)
    from fastapi.staticfiles import StaticFiles

    app.mount("/static", StaticFiles(directory=web_routes.STATIC_DIR), name="static")
    app.mount(docs.DOCS_ASSETS_URL, StaticFiles(directory=docs.DOCS_ASSETS_DIR),
              name="docs-assets")
    templates.add_mount("/static")
    templates.add_mount(docs.DOCS_ASSETS_URL)
    app.add_middleware(BodyLimitMiddleware, max_bytes=settings.max_upload_bytes)
    app.add_middleware(BodyIdleTimeoutMiddleware, idle_s=settings.body_idle_timeout_s)
    app.add_middleware(AuthFailureLimitMiddleware, per_minute=settings.auth_failures_per_minute,
                       max_clients=settings.auth_failure_clients,
                       max_keys=settings.auth_failure_keys, clock=clock)
    app.add_middleware(SecurityHeadersMiddleware)
    # outermost: a request's latency from arrival, refusals by the middlewares above included
    app.add_middleware(RequestMetricsMiddleware, metrics=app.state.metrics,
                       templates=templates)

    return app
