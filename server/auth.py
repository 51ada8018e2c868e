"""API keys: creation, hashing, authentication, the role rules and the session cookie's
CSRF rule.

Keys are 32 random bytes (``secrets.token_urlsafe``) shown once; only their SHA-256 is stored.
A slow password hash is not needed for 256-bit random secrets: nobody can brute-force them.

A write authenticated by the dashboard's session cookie (a form post, or the API called with
the cookie instead of a Bearer key) must carry the session's CSRF token and, when the browser
names an ``Origin``, come from our own (:func:`session_write_refusal`). Browsers send a
``SameSite=Strict`` cookie to every port of the same host, so the cookie alone proves nothing.
"""

from __future__ import annotations

import hashlib
import hmac
import secrets
from collections.abc import Iterable

from sqlalchemy import select
from sqlalchemy.orm import Session

from server.errors import Conflict, NotFound
from server.models import ROLES, ApiKey, utcnow

__all__ = ["KEY_PREFIX", "hash_key", "create_key", "list_keys", "keys_by_id", "authenticate",
           "revoke_key", "ALLOWED",
           "may", "SESSION_COOKIE", "SIGNIN_COOKIE", "CSRF_HEADER", "SAFE_METHODS", "csrf_token",
           "session_write_refusal"]

KEY_PREFIX = "hmsm_"
SESSION_COOKIE = "hmsm_session"
#: the sign-in form's pre-session cookie: random, its CSRF token in the form (login CSRF)
SIGNIN_COOKIE = "hmsm_signin"
#: the header that carries the CSRF token on API writes authenticated by the session cookie
CSRF_HEADER = "X-CSRF-Token"
SAFE_METHODS = frozenset({"GET", "HEAD", "OPTIONS"})

# Which roles may do what. Reads: everyone with a key.
ALLOWED: dict[str, frozenset[str]] = {
    "read": frozenset(ROLES),
    "upload": frozenset({"uploader", "admin"}),
    "operate": frozenset({"operator", "admin"}),
    # maintenance actions (replace, inspect / no fault found, defer): the maintenance engineer
    "maintain": frozenset({"maintainer", "admin"}),
    "admin": frozenset({"admin"}),
}


def may(role: str, action: str) -> bool:
    return role in ALLOWED[action]


def hash_key(plaintext: str) -> str:
    return hashlib.sha256(plaintext.encode()).hexdigest()


def create_key(*, session: Session, name: str, role: str) -> tuple[ApiKey, str]:
    """Register a new key; return the row and the plaintext (shown once, never stored)."""
    if role not in ROLES:
        raise ValueError(f"role must be one of {', '.join(ROLES)}")
    if not name or len(name) > 128:
        raise ValueError("name must be 1-128 characters")
    plaintext = KEY_PREFIX + secrets.token_urlsafe(32)
    row = ApiKey(name=name, role=role, key_hash=hash_key(plaintext), prefix=plaintext[:10])
    session.add(row)
    session.flush()
    return row, plaintext


def list_keys(*, session: Session) -> list[ApiKey]:
    """Every key, revoked ones too, in the order they were made."""
    return list(session.scalars(select(ApiKey).order_by(ApiKey.id)))


def keys_by_id(*, session: Session, key_ids: Iterable[int | None]) -> dict[int, ApiKey]:
    """The keys of these ids (a flight's uploader may be none: ``None`` is skipped)."""
    wanted = {i for i in key_ids if i is not None}
    if not wanted:
        return {}
    return {k.id: k for k in session.scalars(select(ApiKey).where(ApiKey.id.in_(wanted)))}


def authenticate(*, session: Session, plaintext: str) -> ApiKey | None:
    """The active key matching ``plaintext``, or None."""
    if not plaintext.startswith(KEY_PREFIX) or len(plaintext) > 200:
        return None
    row = session.scalar(select(ApiKey).where(ApiKey.key_hash == hash_key(plaintext)))
    if row is None or row.revoked_at is not None:
        return None
    return row


def revoke_key(*, session: Session, key_id: int, keep_an_admin: bool = False) -> ApiKey:
    """Revoke a key. ``keep_an_admin`` (the API): never the last active admin key, which would
    leave nobody to manage keys but the host's ``hmsm keys`` (409 ``last_admin``)."""
    row = session.get(ApiKey, key_id)
    if row is None:
        raise NotFound(f"API key {key_id} does not exist.")
    if keep_an_admin and row.role == "admin" and row.revoked_at is None:
        admins = session.scalars(select(ApiKey.id).where(  # locked: two admins revoking
            ApiKey.role == "admin", ApiKey.revoked_at.is_(None)).with_for_update()).all()
        if list(admins) == [row.id]:
            raise Conflict(f"API key {key_id} is the last active admin key; create another "
                           "admin key before revoking it.", code="last_admin")
    if row.revoked_at is None:
        row.revoked_at = utcnow()
    return row


def csrf_token(session_cookie: str) -> str:
    """HMAC-SHA256 of a fixed label keyed by the cookie value: stateless, bound to the session,
    and not computable by a page that cannot read the HttpOnly cookie."""
    return hmac.new(session_cookie.encode(), b"hmsm-dashboard-csrf", hashlib.sha256).hexdigest()


def session_write_refusal(*, session_cookie: str, presented_token: str | None,
                          origin: str | None, own_origin: str,
                          fetch_site: str | None = None) -> str | None:
    """Why a write authenticated by the session cookie (or the sign-in form's pre-session
    cookie) is refused (``cross_origin``, ``csrf_mismatch``), or None. ``Origin: null`` (sent
    on form posts under ``Referrer-Policy: no-referrer``, ours or a page's that chose it) proves
    nothing either way: the token decides; ``Sec-Fetch-Site`` (``fetch_site``, which no page
    can set) must say ``same-origin`` when the browser sends it."""
    if origin is not None and origin != "null" and origin != own_origin:
        return "cross_origin"
    if fetch_site is not None and fetch_site != "same-origin":
        return "cross_origin"
    if not session_cookie:
        return "csrf_mismatch"
    expected = csrf_token(session_cookie).encode()
    if not presented_token or not hmac.compare_digest(presented_token.encode(), expected):
        return "csrf_mismatch"
    return None
