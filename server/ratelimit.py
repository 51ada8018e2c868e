"""Failed authentications per client address: past a budget, 429 with ``Retry-After``.

A failed authentication is an answer 401 to a request that presented a key (API Bearer key,
the session cookie, or the sign-in form), or the redirect to the sign-in page of a request that
carried the session cookie (the dashboard pages and the API docs). Each client address has a
token bucket of ``per_minute`` failures refilled at ``per_minute`` a minute; a request that
presents a key while its bucket holds less than one failure is answered 429 before anything
is looked up, whatever the key, so guessing runs at ``per_minute`` a minute at most. Requests
that authenticate take nothing from the bucket, and requests without a key are never limited.
At most ``max_clients`` addresses are tracked: past that the one that failed least recently is
forgotten. The address is uvicorn's: the peer's, or ``X-Forwarded-For`` when the peer is in
``FORWARDED_ALLOW_IPS`` (127.0.0.1 by default: a reverse proxy on the host).
"""

from __future__ import annotations

import math
import time
from collections import OrderedDict
from collections.abc import Callable

from starlette.requests import cookie_parser
from starlette.responses import JSONResponse
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from server.auth import SESSION_COOKIE
from server.errors import error_body

__all__ = ["FailureBudget", "AuthFailureLimitMiddleware"]

_SIGNIN_REDIRECT = b"/signin?next="


class FailureBudget:
    """Token buckets of failed authentications, one per client address, bounded in number.

    Used from the event loop only (the middleware), so without a lock."""

    def __init__(self, per_minute: int, max_clients: int,
                 clock: Callable[[], float] = time.monotonic):
        self.per_minute, self.max_clients, self._clock = per_minute, max_clients, clock
        self._buckets: OrderedDict[str, tuple[float, float]] = OrderedDict()  # tokens, at

    def _tokens(self, client: str, now: float) -> float:
        tokens, at = self._buckets.get(client, (self.per_minute, now))
        return min(self.per_minute, tokens + (now - at) * self.per_minute / 60)

    def wait_s(self, client: str) -> float:
        """Seconds until ``client`` may present a key again; 0: now."""
        tokens = self._tokens(client, self._clock())
        return 0.0 if tokens >= 1 else (1 - tokens) * 60 / self.per_minute

    def failed(self, client: str) -> None:
        now = self._clock()
        self._buckets[client] = (max(0.0, self._tokens(client, now) - 1), now)
        self._buckets.move_to_end(client)
        while len(self._buckets) > self.max_clients:
            self._buckets.popitem(last=False)

    def __len__(self) -> int:
        return len(self._buckets)


class AuthFailureLimitMiddleware:
    """Counts failed authentications per client address and refuses a client past its budget
    (module docstring); ``per_minute`` 0 turns it off."""

    def __init__(self, app: ASGIApp, per_minute: int, max_clients: int,
                 clock: Callable[[], float] = time.monotonic):
        self.app = app
        self.budget = FailureBudget(per_minute, max_clients, clock) if per_minute > 0 else None

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http" or self.budget is None:
            await self.app(scope, receive, send)
            return
        headers = dict(scope["headers"])  # the last of a repeated header: only its presence matters
        with_cookie = _has_session_cookie(headers.get(b"cookie", b""))
        presents_key = (b"authorization" in headers or with_cookie
                        or (scope["method"] == "POST" and scope["path"] == "/signin"))
        if not presents_key:
            await self.app(scope, receive, send)
            return
        client = scope["client"][0] if scope.get("client") else "unknown"
        wait = self.budget.wait_s(client)
        if wait > 0:
            seconds = math.ceil(wait)
            response = JSONResponse(error_body(
                "too_many_failures", f"Too many failed authentications from this address; try "
                f"again in {seconds} s.", {"retry_after_s": seconds}), status_code=429,
                headers={"Retry-After": str(seconds)})
            await response(scope, receive, send)
            return
        budget = self.budget

        async def counting_send(message: Message) -> None:
            if message["type"] == "http.response.start":
                status = message["status"]
                location = dict(message.get("headers", [])).get(b"location", b"")
                if status == 401 or (with_cookie and status == 303
                                     and location.startswith(_SIGNIN_REDIRECT)):
                    budget.failed(client)
            await send(message)

        await self.app(scope, receive, counting_send)


def _has_session_cookie(header: bytes) -> bool:
    return bool(cookie_parser(header.decode("latin-1")).get(SESSION_COOKIE))
