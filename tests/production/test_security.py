"""Security behaviour: roles on every write endpoint, key revocation, no path traversal,
size limits, security headers and CSP on the dashboard. See docs/SECURITY.md."""

from __future__ import annotations

import re
from collections.abc import Iterator

import pytest
from fastapi.testclient import TestClient

from server.app import create_app
from server.blobstore import LocalBlobStore
from server.config import Settings
from tests.flightlog_factory import make_parquet, serials_for
from tests.production.helpers import ROLES, seed_system
from tests.signin import sign_in

PARQUET = "application/vnd.apache.parquet"
LIMIT = 1024 * 1024


@pytest.fixture
def api(tmp_path) -> Iterator[tuple[TestClient, dict[str, str], Settings]]:
    # the role walk sends a wrong key to every write endpoint: past the default burst of
    # failed authentications it would read 429s, not the roles (the limit has its own tests)
    settings = Settings(data_dir=tmp_path / "data", max_upload_bytes=LIMIT,
                        auth_failures_per_minute=0)
    keys = seed_system(settings)
    with TestClient(create_app(settings)) as client:
        yield client, keys, settings


def _h(key: str | None, **extra: str) -> dict[str, str]:
    return ({"Authorization": f"Bearer {key}"} if key else {}) | extra


def required_roles(method: str, path: str) -> set[str]:
    """The project's rule (README, "Using the API") for each write endpoint."""
    if path == "/api/v1/flights" and method == "post":
        return {"uploader", "admin"}
    if path.startswith("/api/v1/test-station/"):
        return {"operator", "admin"}
    if re.fullmatch(r"/api/v1/actuators/\{[^}]+\}/(replace|inspect|defer)", path):
        return {"maintainer", "admin"}  # maintenance actions
    return {"admin"}  # fleet, actuator replacement, keys, models, alarms


def write_operations(client: TestClient, key: str) -> list[tuple[str, str]]:
    spec = client.get("/openapi.json", headers=_h(key)).json()
    ops = [(m, p) for p, item in spec["paths"].items() for m in item
           if m in {"post", "put", "patch", "delete"}]
    assert len(ops) >= 12, ops  # aircraft, actuators, flights, alarms, keys, models, station
    return ops


def test_every_write_endpoint_refuses_missing_keys_and_lower_roles(api) -> None:  # type: ignore[no-untyped-def]
    client, keys, _ = api
    checked = 0
    for method, path in write_operations(client, keys["viewer"]):
        url = re.sub(r"\{[^}]+\}", "999999", path)  # no such row: nothing is changed
        allowed = required_roles(method, path)
        r = client.request(method, url, json={})
        assert r.status_code == 401, (method, path, r.text)
        assert r.json()["error"]["code"] == "unauthorized"
        r = client.request(method, url, json={}, headers=_h("hmsm_not-a-real-key"))
        assert r.status_code == 401, (method, path, r.text)
        for role in set(ROLES) - allowed:
            r = client.request(method, url, json={}, headers=_h(keys[role]))
            assert r.status_code == 403, (method, path, role, r.text)
            assert r.json()["error"]["code"] == "forbidden"
        for role in allowed:  # the right role gets past authorisation (to validation etc.)
            r = client.request(method, url, json={}, headers=_h(keys[role]))
            assert r.status_code not in (401, 403), (method, path, role, r.text)
        checked += 1
    assert checked >= 12


def test_revoked_key_is_refused_at_once(api) -> None:  # type: ignore[no-untyped-def]
    client, keys, _ = api
    made = client.post("/api/v1/keys", json={"name": "temp", "role": "viewer"},
                       headers=_h(keys["admin"]))
    assert made.status_code == 201
    new = made.json()
    assert client.get("/api/v1/flights", headers=_h(new["key"])).status_code == 200
    assert client.post(f"/api/v1/keys/{new['id']}/revoke",
                       headers=_h(keys["admin"])).status_code == 200
    r = client.get("/api/v1/flights", headers=_h(new["key"]))
    assert r.status_code == 401 and r.json()["error"]["code"] == "unauthorized"
    listed = client.get("/api/v1/keys", headers=_h(keys["admin"])).json()
    text = str(listed)
    assert new["key"] not in text  # plaintext is shown once, never listed


@pytest.mark.parametrize("name", ["../x", "..", ".", "a/b", "..\\x", "%2e%2e", "x\x00"])
def test_names_that_could_reach_the_filesystem_are_rejected(api, name: str) -> None:  # type: ignore[no-untyped-def]
    client, keys, _ = api
    admin = _h(keys["admin"])
    r = client.post("/api/v1/models/train", json={"campaign": name}, headers=admin)
    assert r.status_code == 422, r.text
    r = client.post("/api/v1/models/train", json={"campaign": "ok", "name": name},
                    headers=admin)
    assert r.status_code == 422, r.text
    if "/" in name or "\\" in name or "%" in name or "\x00" in name:
        r = client.post("/api/v1/aircraft", headers=admin, json={
            "tail": name, "base": "Turin", "actuators": serials_for("T")})
        assert r.status_code == 422, r.text


def test_path_traversal_in_urls_and_channels_finds_nothing(api) -> None:  # type: ignore[no-untyped-def]
    client, keys, settings = api
    admin = _h(keys["admin"])
    assert client.post("/api/v1/aircraft", headers=admin, json={
        "tail": "SEC1", "base": "Turin", "actuators": serials_for("SEC1")}).status_code == 201
    r = client.post("/api/v1/flights", content=make_parquet("SEC1", "F1"),
                    headers=_h(keys["uploader"], **{"Content-Type": PARQUET}))
    assert r.status_code == 202, r.text
    fid = r.json()["id"]
    for url in ("/api/v1/flights/..%2F..%2Fetc%2Fpasswd", "/api/v1/flights/%2e%2e",
                "/api/v1/aircraft/..%2F..%2Fx", "/api/v1/flights/1%2F..%2F..%2Fx/signals"):
        r = client.get(url, headers=admin)
        assert r.status_code in (404, 422), (url, r.text)
        assert r.json()["error"]["code"] in ("not_found", "validation_error")
    r = client.get(f"/api/v1/flights/{fid}/signals", params={"channels": "../../etc/passwd"},
                   headers=admin)
    assert r.status_code == 404 and r.json()["error"]["code"] == "unknown_channel"
    # blob paths come from the SHA-256 alone
    flight = client.get(f"/api/v1/flights/{fid}", headers=admin).json()
    blobs = LocalBlobStore(settings.blob_dir, settings.tmp_dir)
    assert blobs.relative_path(flight["sha256"]).endswith(flight["sha256"])
    for bad in ("../" * 3 + "etc/passwd", "ab/cd/" + "g" * 64, "../" + "a" * 62):
        with pytest.raises(ValueError):
            blobs.relative_path(bad)
    with pytest.raises(ValueError):
        blobs.read("../../../etc/passwd")


def test_upload_size_limit_with_and_without_content_length(api) -> None:  # type: ignore[no-untyped-def]
    client, keys, settings = api
    headers = _h(keys["uploader"], **{"Content-Type": PARQUET})
    too_big = b"\0" * (LIMIT + 128 * 1024)
    r = client.post("/api/v1/flights", content=too_big, headers=headers)
    assert r.status_code == 413 and r.json()["error"]["code"] == "payload_too_large"

    def chunks() -> Iterator[bytes]:  # chunked transfer: no Content-Length to trust
        for _ in range(24):
            yield b"\0" * (64 * 1024)

    r = client.post("/api/v1/flights", content=chunks(), headers=headers)
    assert r.status_code == 413 and r.json()["error"]["code"] == "payload_too_large"
    assert list(settings.tmp_dir.iterdir()) == []  # nothing of it kept
    r = client.post("/api/v1/flights", files={"file": ("f.parquet", too_big, PARQUET)},
                    headers=_h(keys["uploader"]))
    assert r.status_code == 413


def test_dashboard_pages_carry_csp_and_anti_framing_headers(api) -> None:  # type: ignore[no-untyped-def]
    client, keys, _ = api
    r = sign_in(client, keys["viewer"])
    assert r.status_code == 303
    cookie = r.headers["set-cookie"].lower()
    assert "httponly" in cookie and "samesite=strict" in cookie
    for page in ("/fleet", "/alarms", "/models", "/test-station", "/signin"):
        r = client.get(page)
        assert r.status_code == 200, (page, r.status_code)
        csp = r.headers.get("content-security-policy", "")
        assert "default-src 'self'" in csp and "frame-ancestors 'none'" in csp, page
        assert "script-src 'self'" in csp and "unsafe-eval" not in csp, page
        assert r.headers.get("x-frame-options") == "DENY", page
        assert r.headers.get("x-content-type-options") == "nosniff", page
        assert r.headers.get("referrer-policy") == "no-referrer", page
    r = client.get("/api/v1/health/live")
    assert r.headers.get("x-content-type-options") == "nosniff"


def test_signin_redirect_stays_on_this_site(api) -> None:  # type: ignore[no-untyped-def]
    client, keys, _ = api
    for target in ("https://evil.example/", "//evil.example/x", "/\\evil.example"):
        r = sign_in(client, keys["viewer"], next=target)
        location = r.headers.get("location", "")
        assert location.startswith("/") and not location.startswith(("//", "/\\")), location
