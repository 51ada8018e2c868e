"""Signing a test client in through the dashboard's own sign-in form: its page first (the
pre-session cookie and the form's CSRF token), then the post (docs/SECURITY.md, login CSRF)."""

from __future__ import annotations

import re

import httpx
from fastapi.testclient import TestClient

__all__ = ["signin_token", "sign_in"]


def signin_token(client: TestClient) -> str:
    """The sign-in form's CSRF token; the pre-session cookie is now in ``client``."""
    page = client.get("/signin")
    found = re.search(r'action="/signin">.*?name="csrf" value="([^"]+)"', page.text, re.S)
    assert found, page.text[:500]
    return found.group(1)


def sign_in(client: TestClient, key: str, next: str = "/fleet") -> httpx.Response:
    """The form's post with ``key`` (not followed: 303 on success, 401 for a wrong key)."""
    return client.post("/signin", data={"key": key, "next": next, "csrf": signin_token(client)},
                       follow_redirects=False)
