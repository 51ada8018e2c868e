"""Live updates: ``GET /api/v1/events``, a server-sent-event stream fed by polling the database.

Every ``poll_s`` seconds (default 1.5 s) one short read transaction takes a *snapshot* of a few
aggregates -- the largest alarm / health-record / prognosis / injection / model ids, and
fingerprints of the alarm and injection status changes (counts per status and the latest
acknowledge / close times). Each aggregate that changed since the previous snapshot becomes one
event; the work per poll is a fixed number of indexed queries, whatever the fleet size, and it
works the same with several API processes or workers on other machines (no in-process bus).

Events (``event:`` name, JSON ``data``)::

    alarm          a new alarm was raised            {"max_id": int}
    alarm-status   an alarm was acknowledged/closed  {"fingerprint": str}
    flight         a flight was analysed             {"max_health_record_id": int}
    prognosis      a new RUL prediction              {"max_id": int}
    injection      a test-station injection changed  {"fingerprint": str}
    model          a model version changed           {"fingerprint": str}

A comment line is sent every ``keepalive_s`` seconds; the stream ends after ``timeout`` seconds
(the browser's EventSource reconnects by itself after ``retry`` ms). Each poll also checks, in
the same short transaction (one indexed query), that the stream's key is still active: once it
is revoked the stream sends ``revoked`` and ends, and the reconnect gets 401.
"""

from __future__ import annotations

import asyncio
import json
import time
from collections.abc import AsyncIterator
from typing import Annotated, Any

from anyio import to_thread
from fastapi import APIRouter, Depends, Query, Request
from fastapi.responses import StreamingResponse
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer

from server.auth import SESSION_COOKIE
from server.db import SessionFactory
from server.errors import Unauthorized
from server.services.events import key_is_active, snapshot_while_active

__all__ = ["router", "diff_events", "POLL_S"]

POLL_S = 1.5
KEEPALIVE_S = 15.0
_bearer = HTTPBearer(auto_error=False)

router = APIRouter(tags=["events"])


def diff_events(before: dict[str, Any], after: dict[str, Any]) -> list[tuple[str, dict[str, Any]]]:
    """Events for the aggregates that changed between two snapshots."""
    keys = {"alarm": "max_id", "flight": "max_health_record_id", "prognosis": "max_id"}
    out = []
    for name, value in after.items():
        if before.get(name) != value:
            out.append((name, {keys.get(name, "fingerprint"): value}))
    return out


def _format(event: str, data: dict[str, Any]) -> str:
    return f"event: {event}\ndata: {json.dumps(data)}\n\n"


def _authenticate(factory: SessionFactory, token: str | None) -> str:
    if not token:
        raise Unauthorized("An API key is required (Authorization: Bearer ... or the "
                           "hmsm_session cookie).", headers={"WWW-Authenticate": "Bearer"})
    if not key_is_active(factory, token):
        raise Unauthorized("The API key is unknown or revoked.",
                           headers={"WWW-Authenticate": "Bearer"})
    return token


async def _stream(request: Request, factory: SessionFactory, token: str, *,
                  poll_s: float, timeout_s: float) -> AsyncIterator[str]:
    yield "retry: 2000\n\n"
    state = await to_thread.run_sync(snapshot_while_active, factory, token)
    if state is None:
        return
    yield _format("hello", {"poll_s": poll_s})
    started = last_sent = time.monotonic()
    while time.monotonic() - started < timeout_s:
        await asyncio.sleep(poll_s)
        if await request.is_disconnected():
            return
        new = await to_thread.run_sync(snapshot_while_active, factory, token)
        if new is None:
            yield _format("revoked", {})
            return
        for name, data in diff_events(state, new):
            yield _format(name, data)
            last_sent = time.monotonic()
        state = new
        if time.monotonic() - last_sent >= KEEPALIVE_S:
            yield ": keepalive\n\n"
            last_sent = time.monotonic()


@router.get("/events", summary="Live updates as server-sent events (text/event-stream)",
            response_class=StreamingResponse,
            responses={200: {"content": {"text/event-stream": {}}}})
async def events(
    request: Request,
    credentials: Annotated[HTTPAuthorizationCredentials | None, Depends(_bearer)],
    timeout: Annotated[float, Query(ge=1, le=3600, description="Seconds before the stream "
                                    "ends (the browser reconnects).")] = 300,
    poll: Annotated[float, Query(ge=0.2, le=30, description="Polling period [s].")] = POLL_S,
) -> StreamingResponse:
    """Any valid key (viewer and up). The session is held only while polling, not in between."""
    factory: SessionFactory = request.app.state.session_factory
    token = credentials.credentials if credentials else request.cookies.get(SESSION_COOKIE)
    token = await to_thread.run_sync(_authenticate, factory, token)
    return StreamingResponse(_stream(request, factory, token, poll_s=poll, timeout_s=timeout),
                             media_type="text/event-stream",
                             headers={"Cache-Control": "no-store", "X-Accel-Buffering": "no"})
