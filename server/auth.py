"""API keys: creation, hashing, authentication and the role rules.

Keys are 32 random bytes (``secrets.token_urlsafe``) shown once; only their SHA-256 is stored.
A slow password hash is not needed for 256-bit random secrets: nobody can brute-force them.
"""

from __future__ import annotations

import hashlib
import secrets

from sqlalchemy import select
from sqlalchemy.orm import Session

from server.errors import NotFound
from server.models import ROLES, ApiKey, utcnow

__all__ = ["KEY_PREFIX", "hash_key", "create_key", "authenticate", "revoke_key", "ALLOWED",
           "may"]

KEY_PREFIX = "hmsm_"

# Which roles may do what. Reads: everyone with a key.
ALLOWED: dict[str, frozenset[str]] = {
    "read": frozenset(ROLES),
    "upload": frozenset({"uploader", "admin"}),
    "operate": frozenset({"operator", "admin"}),
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


def authenticate(*, session: Session, plaintext: str) -> ApiKey | None:
    """The active key matching ``plaintext``, or None."""
    if not plaintext.startswith(KEY_PREFIX) or len(plaintext) > 200:
        return None
    row = session.scalar(select(ApiKey).where(ApiKey.key_hash == hash_key(plaintext)))
    if row is None or row.revoked_at is not None:
        return None
    return row


def revoke_key(*, session: Session, key_id: int) -> ApiKey:
    row = session.get(ApiKey, key_id)
    if row is None:
        raise NotFound(f"API key {key_id} does not exist.")
    if row.revoked_at is None:
        row.revoked_at = utcnow()
    return row
