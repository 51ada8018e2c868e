"""Failed authentications per presented key and per client address: past a budget, 429 with
``Retry-After``; a right key is never refused.

A failed authentication is an answer 401 to a request that presented a key (API Bearer key,
the session cookie, or the sign-in form), or the redirect to the sign-in page of a request that
carried the session cookie (the dashboard pages and the API docs). Two kinds of token bucket,
each of ``per_minute`` failures refilled at ``per_minute`` a minute, count them separately:

- per presented key, named by its SHA-256 (``server.auth.hash_key``, what the database
  stores of a key: no secret is kept here, and only keys that failed are tracked). A key
  whose bucket is empty is answered 429 before anything is looked up, from any address. A
  right key never fails, so its bucket is never spent: one key's failures never refuse
  another key. The sign-in form's key travels in the body, which this middleware does not
  read: only the address counts its failures.
- per client address. Its bucket never refuses a request by itself: the key is looked up as
  usual, a right one is served, and a wrong one answered 429 instead of 401. So a neighbour
  behind the same NAT, or a reverse proxy outside ``FORWARDED_ALLOW_IPS`` that gives every
  user one address, cannot lock a user out by failing.

Refused requests count as failures too: a client that does not wait for ``Retry-After`` stays
refused. Requests that authenticate take nothing, and requests without a key are never
limited. At most ``max_clients`` addresses and ``max_keys`` keys are tracked: past that the one
that failed least recently is forgotten. The address is uvicorn's: the peer's, or
``X-Forwarded-For`` when the peer is in ``FORWARDED_ALLOW_IPS`` (127.0.0.1 by default: a
reverse proxy on the host).

What this gives up: an address past its budget still learns, by 200 against 429, whether a new
key it tries is right, at whatever rate it sends. Keys are 256 random bits and the metrics token
at least 128: no rate of guessing finds one; the limit keeps failing clients told to wait and
answers a repeated wrong key without a database lookup (docs/SECURITY.md).
"""

from __future__ import annotations

import math
import time
from collections import OrderedDict
from collections.abc import Callable

from starlette.requests import cookie_parser
from starlette.responses import JSONResponse
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from server.auth import SESSION_COOKIE, hash_key
from server.errors import error_body

__all__ = ["FailureBudget", "AuthFailureLimitMiddleware"]

_SIGNIN_REDIRECT = b"/signin?next="


class FailureBudget:
    """Token buckets of failed authentications, one per name (a client address or a key's
    hash), bounded in number.

    Used from the event loop only (the middleware), so without a lock."""

    def __init__(self, per_minute: int, max_clients: int,
                 clock: Callable[[], float] = time.monotonic):
        self.per_minute, self.max_clients, self._clock = per_minute, max_clients, clock
        self._buckets: OrderedDict[str, tuple[float, float]] = OrderedDict()  # tokens, at

    def _tokens(self, client: str, now: float) -> float:
        tokens, at = self._buckets.get(client, (self.per_minute, now))
        return min(self.per_minute, tokens + (now - at) * self.per_minute / 60)

    def wait_s(self, client: str) -> float:
        """Seconds until ``client`` may fail again; 0: now."""
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
    """Counts failed authentications per presented key and per client address, and answers a
    wrong key past either budget 429 (module docstring); ``per_minute`` 0 turns it off."""

    def __init__(self, app: ASGIApp, per_minute: int, max_clients: int, max_keys: int,
                 clock: Callable[[], float] = time.monotonic):
        self.app = app
        self.addresses = FailureBudget(per_minute, max_clients, clock) if per_minute > 0 else None
        self.keys = FailureBudget(per_minute, max_keys, clock) if per_minute > 0 else None

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http" or self.addresses is None or self.keys is None:
            await self.app(scope, receive, send)
            return
        headers: dict[bytes, bytes] = {}
        for name, value in scope["headers"]:  # the first of a repeated header: what the app reads
            headers.setdefault(name, value)
        cookie = _session_cookie(headers.get(b"cookie", b""))
        signin = scope["method"] == "POST" and scope["path"] == "/signin"
        if b"authorization" not in headers and not cookie and not signin:
            await self.app(scope, receive, send)
            return
        addresses, keys = self.addresses, self.keys
        client = scope["client"][0] if scope.get("client") else "unknown"
        # the form's key is in the body; a cookie beside it is not what the form presents
        key = None if signin else hash_key(_presented(headers, cookie))

        def fail() -> None:
            addresses.failed(client)
            if key is not None:
                keys.failed(key)

        key_wait = keys.wait_s(key) if key is not None else 0.0
        if key_wait > 0:  # this very key failed its budget's worth: it is wrong, not looked up
            fail()
            await _too_many(key_wait, "with this key")(scope, receive, send)
            return
        address_wait = addresses.wait_s(client)
        replaced = False

        async def counting_send(message: Message) -> None:
            nonlocal replaced
            if replaced:  # the app's body of a failure answered 429 instead
                return
            if message["type"] == "http.response.start":
                status = message["status"]
                location = dict(message.get("headers", [])).get(b"location", b"")
                if status == 401 or (cookie and status == 303
                                     and location.startswith(_SIGNIN_REDIRECT)):
                    fail()
                    if address_wait > 0:
                        replaced = True
                        await _too_many(address_wait, "from this address")(scope, receive,
                                                                           send)
                        return
            await send(message)

        await self.app(scope, receive, counting_send)


def _too_many(wait_s: float, where: str) -> JSONResponse:
    seconds = math.ceil(wait_s)
    return JSONResponse(error_body(
        "too_many_failures", f"Too many failed authentications {where}; try again in "
        f"{seconds} s.", {"retry_after_s": seconds}), status_code=429,
        headers={"Retry-After": str(seconds)})


def _session_cookie(header: bytes) -> str:
    return cookie_parser(header.decode("latin-1")).get(SESSION_COOKIE, "")


def _presented(headers: dict[bytes, bytes], cookie: str) -> str:
    """The key the app will check (``server.api.deps.presented_key``): a Bearer credential,
    else the session cookie; else the ``Authorization`` header as it is."""
    authorization = headers.get(b"authorization", b"").decode("latin-1")
    scheme, _, credentials = authorization.partition(" ")
    if scheme.lower() == "bearer" and credentials.strip():
        return credentials.strip()
    return cookie or authorization
