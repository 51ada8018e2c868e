"""Requests a browser or a careless client can send (issue 26): writes through the session
cookie (CSRF), the API documentation and its key rule, the error responses the schema lists,
body limits, strict integers, finite floats, ASCII ids, the event stream of a revoked key and
the temporary files a killed process leaves."""

from __future__ import annotations

import os
import re
import threading
import time
from collections.abc import Iterator

import pytest
from fastapi.testclient import TestClient

from server.app import create_app
from server.auth import csrf_token
from server.config import Settings
from tests.api.conftest import auth
from tests.flightlog_factory import make_parquet, serials_for
from tests.signin import sign_in as sign_in_form
from tests.signin import signin_token

PARQUET = {"Content-Type": "application/vnd.apache.parquet"}
OWN_ORIGIN = "http://testserver"


def sign_in(client: TestClient, key: str) -> None:
    r = sign_in_form(client, key)
    assert r.status_code == 303, r.text


def _new_key(client: TestClient, admin: str, role: str = "viewer") -> dict:  # type: ignore[type-arg]
    r = client.post("/api/v1/keys", json={"name": f"temp-{role}", "role": role},
                    headers=auth(admin))
    assert r.status_code == 201, r.text
    return r.json()


def _revoked(client: TestClient, admin: str, key_id: int) -> bool:
    keys = client.get("/api/v1/keys", headers=auth(admin)).json()
    return next(k for k in keys if k["id"] == key_id)["revoked_at"] is not None


# ------------------------------------------------------------------------------------------
# CSRF: writes authenticated by the session cookie
# ------------------------------------------------------------------------------------------


def test_cookie_writes_need_the_session_csrf_token(client: TestClient, keys: dict[str, str],
                                                   aircraft: str) -> None:
    victim = _new_key(client, keys["admin"])
    sign_in(client, keys["admin"])
    url = f"/api/v1/keys/{victim['id']}/revoke"
    for headers in ({}, {"X-CSRF-Token": "0" * 64}, {"X-CSRF-Token": "é".encode("latin-1")}):
        r = client.post(url, headers=headers)
        assert r.status_code == 403, (headers, r.text)
        assert r.json()["error"]["code"] == "csrf_mismatch"
    token = csrf_token(keys["admin"])
    r = client.post(url, headers={"X-CSRF-Token": token, "Origin": "http://127.0.0.1:9999"})
    assert r.status_code == 403 and r.json()["error"]["code"] == "cross_origin"
    forged = client.post("/api/v1/flights", content=make_parquet(aircraft, "FORGED"),
                         headers=PARQUET)
    assert forged.status_code == 403
    assert not _revoked(client, keys["admin"], victim["id"])
    assert client.get("/api/v1/flights").json()["total"] == 0  # reads need no token

    r = client.post(url, headers={"X-CSRF-Token": token, "Origin": OWN_ORIGIN})
    assert r.status_code == 200 and _revoked(client, keys["admin"], victim["id"])
    assert f'<meta name="hmsm-csrf" content="{token}">' in client.get("/fleet").text


def test_bearer_writes_need_no_csrf_token_even_beside_a_cookie(
        client: TestClient, keys: dict[str, str], aircraft: str) -> None:
    sign_in(client, keys["viewer"])  # a cookie of another key is ignored under a Bearer key
    r = client.post("/api/v1/flights", content=make_parquet(aircraft, "F0001"),
                    headers={**PARQUET, **auth(keys["uploader"]),
                             "Origin": "http://127.0.0.1:9999"})
    assert r.status_code == 202, r.text


def test_signin_and_signout_come_only_from_this_sites_forms(app, client: TestClient,
                                                           keys: dict[str, str]) -> None:
    """Login CSRF: a page on another port of the host posts the sign-in form with a key of
    its choosing, so that the victim works (and uploads, acknowledges...) under it."""
    attacker = TestClient(app)  # its own pre-session cookie, so its own valid token
    attacker_token = signin_token(attacker)
    token = signin_token(client)
    form = {"key": keys["viewer"], "next": "/fleet"}
    for fields, headers in (
            ({}, {}),  # no token (the victim never loaded the form)
            ({"csrf": attacker_token}, {}),  # a token of another pre-session cookie
            ({"csrf": token}, {"Origin": "http://testserver:9999"}),  # the right one, elsewhere
            ({"csrf": token}, {"Origin": "null", "Sec-Fetch-Site": "same-site"}),
            ({"csrf": token}, {"Sec-Fetch-Site": "cross-site"})):
        r = client.post("/signin", data={**form, **fields}, headers=headers,
                        follow_redirects=False)
        assert r.status_code == 403, (fields, headers, r.status_code)
        assert "Sign-in refused" in r.text and "hmsm_session" not in r.headers.get(
            "set-cookie", "")
        assert "hmsm_session" not in client.cookies
    fresh = TestClient(app)  # a victim without the pre-session cookie: not even a token helps
    r = fresh.post("/signin", data={**form, "csrf": token}, follow_redirects=False)
    assert r.status_code == 403 and "hmsm_session" not in r.headers.get("set-cookie", "")

    # the form as a browser posts it: Origin null (Referrer-Policy: no-referrer), same-origin
    r = client.post("/signin", data={**form, "csrf": token}, follow_redirects=False,
                    headers={"Origin": "null", "Sec-Fetch-Site": "same-origin"})
    assert r.status_code == 303 and client.cookies.get("hmsm_session") == keys["viewer"]

    for fields, headers in (({}, {}), ({"csrf": csrf_token(keys["viewer"])},
                                       {"Sec-Fetch-Site": "same-site"})):
        r = client.post("/signout", data=fields, headers=headers, follow_redirects=False)
        assert r.status_code == 403 and "set-cookie" not in r.headers
    r = client.post("/signout", data={"csrf": csrf_token(keys["viewer"])},
                    headers={"Origin": OWN_ORIGIN, "Sec-Fetch-Site": "same-origin"},
                    follow_redirects=False)
    assert r.status_code == 303 and 'hmsm_session=""' in r.headers["set-cookie"]


# ------------------------------------------------------------------------------------------
# API documentation
# ------------------------------------------------------------------------------------------

_ASSET = re.compile(r'(?:src|href)="([^"]+)"')


def test_docs_need_a_key_and_load_only_local_assets(client: TestClient, keys: dict[str, str]
                                                    ) -> None:
    assert client.get("/openapi.json").status_code == 401
    for page in ("/docs", "/redoc"):
        r = client.get(page, follow_redirects=False)
        assert r.status_code == 303 and r.headers["location"] == f"/signin?next=%2F{page[1:]}"
    dashboard_csp = client.get("/signin").headers["content-security-policy"]
    assert client.get("/openapi.json", headers=auth(keys["viewer"])).status_code == 200
    sign_in(client, keys["viewer"])
    for page in ("/docs", "/redoc"):
        r = client.get(page)
        assert r.status_code == 200, page
        assert r.headers["content-security-policy"] == dashboard_csp
        assert "<script>" not in r.text  # no inline script, as the CSP demands
        assets = _ASSET.findall(r.text)
        assert assets and all(a.startswith("/") and not a.startswith("//") for a in assets)
        for asset in assets:
            got = client.get(asset)
            assert got.status_code == 200 and len(got.content) > 100, asset
    assert client.get("/openapi.json").json()["info"]["title"].startswith("EMA")
    assert 'name="hmsm-csrf" content="' + csrf_token(keys["viewer"]) in client.get("/docs").text


# ------------------------------------------------------------------------------------------
# the error responses of the OpenAPI schema against what the operations answer
# ------------------------------------------------------------------------------------------

LIMIT = 4096
OVER_LIMIT = LIMIT + 64 * 1024 + 1  # the limit holds multipart framing beside the file


@pytest.fixture
def small_client(settings: Settings) -> Iterator[tuple[TestClient, dict[str, str]]]:
    from server.auth import create_key
    from server.db import session_scope

    # many wrong keys: no limit on failed authentications, which would answer 429 to the rest
    app = create_app(settings.model_copy(update={"max_upload_bytes": LIMIT,
                                                 "auth_failures_per_minute": 0}))
    with session_scope(app.state.session_factory) as s:
        keys = {r: create_key(session=s, name=r, role=r)[1] for r in ("viewer", "admin")}
    with TestClient(app, raise_server_exceptions=False) as client:
        yield client, keys
    app.state.engine.dispose()


def _probes(method: str, path: str, operation: dict, keys: dict[str, str]  # type: ignore[type-arg]
            ) -> Iterator[tuple[str, dict]]:  # type: ignore[type-arg]
    url = re.sub(r"\{[^}]+\}", "999999", path)
    yield url, {}
    yield url, {"headers": auth("hmsm_not-a-real-key")}
    for role in ("viewer", "admin"):
        yield url, {"headers": auth(keys[role])}
        if "requestBody" in operation:
            json_body = "application/json" in operation["requestBody"]["content"]
            ctype = "application/json" if json_body else "application/vnd.apache.parquet"
            yield url, {"headers": {**auth(keys[role]), "Content-Type": ctype},
                        "content": b"\xff\xfe{"}
            yield url, {"headers": {**auth(keys[role]), "Content-Type": ctype},
                        "content": iter([b" " * OVER_LIMIT])}  # chunked, over the limit
            yield url, {"headers": auth(keys[role]), "json": {}}


def test_openapi_lists_every_error_an_operation_answers(small_client) -> None:  # type: ignore[no-untyped-def]
    client, keys = small_client
    spec = client.get("/openapi.json", headers=auth(keys["viewer"])).json()
    missing = []
    for path, item in spec["paths"].items():
        for method, operation in item.items():
            if path.startswith("/api/v1/health/"):
                continue
            documented = set(operation["responses"])
            for url, kwargs in _probes(method, path, operation, keys):
                if path == "/api/v1/events":
                    url += "?timeout=1&poll=0.2"
                status = client.request(method, url, **kwargs).status_code
                if str(status) not in documented:
                    missing.append(f"{method.upper()} {path}: {status}")
    assert not missing, sorted(set(missing))
    assert "Error" in spec["components"]["schemas"]
    for path, item in spec["paths"].items():
        for method, operation in item.items():
            for status, response in operation["responses"].items():
                if status[0] == "4":
                    assert response["content"]["application/json"]["schema"] == {
                        "$ref": "#/components/schemas/Error"}, (method, path, status)
    conflicts = {("post", "/api/v1/aircraft"), ("post", "/api/v1/flights"),
                 ("post", "/api/v1/models/{model_id}/activate"),
                 ("post", "/api/v1/test-station/injections"),
                 ("post", "/api/v1/alarms/{alarm_id}/close")}
    for method, path in conflicts:
        assert "409" in spec["paths"][path][method]["responses"], (method, path)


def test_chunked_json_over_the_body_limit_answers_413(small_client) -> None:  # type: ignore[no-untyped-def]
    client, keys = small_client
    r = client.post("/api/v1/aircraft", content=iter([b" " * OVER_LIMIT, b"{}"]),
                    headers={**auth(keys["admin"]), "Content-Type": "application/json"})
    assert r.status_code == 413, r.text
    assert r.json()["error"]["code"] == "payload_too_large"
    assert r.json()["error"]["details"]["limit_bytes"] > LIMIT


def test_get_of_the_training_endpoint_is_405(client: TestClient, keys: dict[str, str]) -> None:
    r = client.get("/api/v1/models/train", headers=auth(keys["viewer"]))
    assert r.status_code == 405 and r.json()["error"]["code"] == "method_not_allowed"
    assert client.get("/api/v1/models/424242", headers=auth(keys["viewer"])).status_code == 404


# ------------------------------------------------------------------------------------------
# values: strict integers, finite floats, ASCII ids
# ------------------------------------------------------------------------------------------


def _injection(client: TestClient, keys: dict[str, str], aircraft: str) -> int:
    r = client.post("/api/v1/test-station/injections", headers=auth(keys["operator"]), json={
        "aircraft": aircraft, "position": "WT", "fault_mode": "MTWEAR", "onset_flight": 2})
    assert r.status_code == 201, r.text
    return int(r.json()["id"])


def test_ground_truth_refuses_non_finite_numbers(client: TestClient, keys: dict[str, str],
                                                 aircraft: str) -> None:
    url = f"/api/v1/test-station/injections/{_injection(client, keys, aircraft)}/ground-truth"
    headers = {**auth(keys["operator"]), "Content-Type": "application/json"}
    for value in ("Infinity", "NaN", "-Infinity", "1e400"):
        body = f'{{"flight": "F1", "flight_number": 1, "severity": {value}, "severity_norm": 0}}'
        r = client.put(url, content=body, headers=headers)
        assert r.status_code == 422, (value, r.text)
    ok = client.put(url, headers=headers, json={"flight": "F1", "flight_number": 1,
                                                "severity": 0.2, "severity_norm": 0.1})
    assert ok.status_code == 200 and ok.json()["severity"] == 0.2
    assert client.get(url, headers=auth(keys["viewer"])).json()[0]["severity"] == 0.2
    assert client.get("/api/v1/test-station/injections/424242/ground-truth",
                      headers=auth(keys["viewer"])).status_code == 404


def test_booleans_are_not_integers(client: TestClient, keys: dict[str, str], aircraft: str
                                   ) -> None:
    r = client.post("/api/v1/test-station/injections", headers=auth(keys["operator"]), json={
        "aircraft": aircraft, "position": "WT", "fault_mode": "MTWEAR", "onset_flight": False})
    assert r.status_code == 422, r.text
    r = client.post("/api/v1/models/train", headers=auth(keys["admin"]),
                    json={"campaign": "c", "seed": True})
    assert r.status_code == 422, r.text
    url = f"/api/v1/test-station/injections/{_injection(client, keys, aircraft)}"
    for body in ({"flight": "F1", "flight_number": True, "severity": 0.1, "severity_norm": 0.1},
                 {"flight": "F1", "flight_number": 1, "severity": 0.1, "severity_norm": 0.1,
                  "true_rul_flights": False}):
        assert client.put(url + "/ground-truth", json=body,
                          headers=auth(keys["operator"])).status_code == 422, body
    r = client.post(url + "/status", json={"status": "active", "failure_flight": True},
                    headers=auth(keys["operator"]))
    assert r.status_code == 422


@pytest.mark.parametrize("flight", ["..", ".", "\uff26\uff11", "F1\u00e9", "F1\n"])
def test_flight_ids_are_ascii_and_not_only_dots(client: TestClient, keys: dict[str, str],
                                                aircraft: str, flight: str) -> None:
    r = client.post("/api/v1/flights", content=make_parquet(aircraft, flight),
                    headers={**PARQUET, **auth(keys["uploader"])})
    assert r.status_code == 422
    assert [x["code"] for x in r.json()["error"]["details"]["reasons"]] == ["bad_metadata"]
    url = f"/api/v1/test-station/injections/{_injection(client, keys, aircraft)}/ground-truth"
    r = client.put(url, headers=auth(keys["operator"]), json={
        "flight": flight, "flight_number": 1, "severity": 0.1, "severity_norm": 0.1})
    assert r.status_code == 422
    r = client.post("/api/v1/aircraft", headers=auth(keys["admin"]), json={
        "tail": flight, "base": "Turin", "actuators": serials_for("X")})
    assert r.status_code == 422


def test_dotted_ids_that_are_not_only_dots_are_fine(client: TestClient, keys: dict[str, str],
                                                    aircraft: str) -> None:
    r = client.post("/api/v1/flights", content=make_parquet(aircraft, "F.1..2"),
                    headers={**PARQUET, **auth(keys["uploader"])})
    assert r.status_code == 202, r.text


# ------------------------------------------------------------------------------------------
# the event stream of a revoked key; temporary files of a killed process
# ------------------------------------------------------------------------------------------


def test_event_stream_ends_when_its_key_is_revoked(client: TestClient, keys: dict[str, str]
                                                   ) -> None:
    viewer = _new_key(client, keys["admin"])
    revoke = threading.Timer(0.8, lambda: client.post(
        f"/api/v1/keys/{viewer['id']}/revoke", headers=auth(keys["admin"])))
    started = time.monotonic()
    revoke.start()
    with client.stream("GET", "/api/v1/events?timeout=20&poll=0.2",
                       headers=auth(viewer["key"])) as r:
        assert r.status_code == 200
        body = "".join(r.iter_text())
    revoke.join()
    assert "event: hello" in body and body.endswith("event: revoked\ndata: {}\n\n")
    assert time.monotonic() - started < 10
    assert client.get("/api/v1/events?timeout=1", headers=auth(viewer["key"])).status_code == 401


def test_stale_temporary_uploads_are_swept_at_start(settings: Settings) -> None:
    tmp = settings.tmp_dir
    tmp.mkdir(parents=True)
    stale = [tmp / f"upload-killed{i}" for i in range(5)]
    for path in stale:
        path.write_bytes(b"\0" * 1024)
        old = time.time() - 3600
        os.utime(path, (old, old))
    live = tmp / "upload-in-flight"
    live.write_bytes(b"\0")
    app = create_app(settings)
    app.state.engine.dispose()
    assert not any(p.exists() for p in stale)
    assert live.exists()  # maybe another API process's upload


# ------------------------------------------------------------------------------------------
# numbers beyond what they can mean: 422 in the error envelope, never a database error
# ------------------------------------------------------------------------------------------

BIG = 442817151593597894656  # beyond 64 bits


def _refused_422(r) -> None:  # type: ignore[no-untyped-def]
    assert r.status_code == 422, r.text[:300]
    error = r.json()["error"]
    assert set(error) == {"code", "message", "details"} and error["code"] == "validation_error"


def test_absurd_numbers_in_bodies_are_refused(client: TestClient, keys: dict[str, str],
                                              aircraft: str) -> None:
    injection = _injection(client, keys, aircraft)
    op = auth(keys["operator"])
    truth = f"/api/v1/test-station/injections/{injection}/ground-truth"
    ok = {"flight": "F1", "flight_number": 1, "severity": 2e-4, "severity_norm": 0.7,
          "true_rul_flights": 80}
    for change in ({"severity": 1e308}, {"severity_norm": 1e308}, {"severity": 10.5},
                   {"flight_number": 2**63 - 1}, {"flight_number": 2**31},
                   {"true_rul_flights": 2**31}):
        _refused_422(client.put(truth, json={**ok, **change}, headers=op))
    assert client.put(truth, json={**ok, "flight_number": 2**31 - 1}, headers=op).status_code == 200
    status = f"/api/v1/test-station/injections/{injection}/status"
    for change in ({"failure_flight": 2**62}, {"planned_failure_flight": 2**31}):
        _refused_422(client.post(status, json={"status": "active", **change}, headers=op))
    se = {"aircraft": aircraft, "position": "WL1", "fault_mode": "SE"}
    for severity in (1e-320, 0.005, 1.5):
        _refused_422(client.post("/api/v1/test-station/injections", headers=op,
                                 json={**se, "severity": severity}))
    assert client.post(f"/api/v1/test-station/injections/{injection}/cancel",
                       headers=op).status_code == 200
    assert client.post("/api/v1/test-station/injections", headers=op,
                       json={**se, "severity": 0.01}).status_code == 201


@pytest.mark.parametrize("path", ["/api/v1/jobs", "/api/v1/flights", "/api/v1/aircraft",
                                  "/api/v1/actuators", "/api/v1/alarms",
                                  "/api/v1/test-station/injections"])
def test_list_offsets_beyond_an_integer_column_are_refused(client: TestClient,
                                                           keys: dict[str, str],
                                                           path: str) -> None:
    viewer = auth(keys["viewer"])
    for offset in (BIG, 2**63, 2**31):
        _refused_422(client.get(f"{path}?offset={offset}", headers=viewer))
    r = client.get(f"{path}?offset={2**31 - 1}", headers=viewer)
    assert r.status_code == 200 and r.json()["items"] == []


def test_jobs_of_an_impossible_flight_id_are_refused(client: TestClient,
                                                    keys: dict[str, str]) -> None:
    _refused_422(client.get(f"/api/v1/jobs?flight_id={BIG}", headers=auth(keys["viewer"])))


@pytest.mark.parametrize("block_hours", ["1e308", "25", "0", "inf"])
def test_flight_of_absurd_block_hours_is_refused_as_bad_metadata(
        client: TestClient, keys: dict[str, str], aircraft: str, block_hours: str) -> None:
    from tests.bombs import plain_csv
    from tests.flightlog_factory import make_log

    log = make_log(aircraft, "F0042")
    meta = {**log.metadata.to_strings(), "block_hours": block_hours}
    r = client.post("/api/v1/flights", headers=auth(keys["uploader"]), data=meta,
                    files={"file": ("f.csv", plain_csv(log.channels))})
    assert r.status_code == 422, r.text[:300]
    reasons = r.json()["error"]["details"]["reasons"]
    assert reasons[0]["code"] == "bad_metadata" and "block_hours" in reasons[0]["details"][
        "fields"]
    assert client.get(f"/api/v1/flights?aircraft={aircraft}",
                      headers=auth(keys["viewer"])).json()["items"][0]["block_hours"] is None


def test_the_last_active_admin_key_cannot_be_revoked(client: TestClient,
                                                    keys: dict[str, str]) -> None:
    admin = auth(keys["admin"])
    listed = client.get("/api/v1/keys", headers=admin).json()
    own = next(k["id"] for k in listed if k["name"] == "test-admin")
    r = client.post(f"/api/v1/keys/{own}/revoke", headers=admin)
    assert r.status_code == 409 and r.json()["error"]["code"] == "last_admin", r.text
    assert "last active admin" in r.json()["error"]["message"]
    assert client.get("/api/v1/keys", headers=admin).status_code == 200  # still works
    other = client.post("/api/v1/keys", headers=admin, json={"name": "second", "role": "admin"})
    assert client.post(f"/api/v1/keys/{own}/revoke", headers=admin).status_code == 200
    second = auth(other.json()["key"])
    r = client.post(f"/api/v1/keys/{other.json()['id']}/revoke", headers=second)
    assert r.status_code == 409  # now the last one itself
    assert client.post(f"/api/v1/keys/{own}/revoke", headers=second).status_code == 200


def test_a_wrong_method_is_answered_with_every_method_of_the_path(client: TestClient) -> None:
    for path, methods in (("/api/v1/flights", {"GET", "HEAD", "POST"}),
                          ("/api/v1/test-station/injections/1/ground-truth",
                           {"GET", "HEAD", "PUT"})):
        for method in ("OPTIONS", "DELETE"):
            r = client.request(method, path)
            assert r.status_code == 405
            assert set(r.headers["allow"].split(", ")) == methods, r.headers["allow"]
