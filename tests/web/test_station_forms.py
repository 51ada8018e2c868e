"""The test-station page's sensor and condition forms through the TestClient: an operator
creates each, the API's schema refuses what it refuses (its message on the page, nothing
stored), a second live one of a kind is a 409 on the page, and a viewer or a post without the
session's CSRF token is refused. The browser's side (390 px, the lists): tests/browser."""

from __future__ import annotations

import html

from sqlalchemy import func, select

from server.db import session_scope
from server.models import SensorInjection, SimCondition
from server.schemas import SensorInjectionCreate, condition_range
from server.web.routes import csrf_token
from tests.signin import sign_in


def _count(client, model) -> int:  # type: ignore[no-untyped-def]
    with session_scope(client.app.state.session_factory) as s:
        return int(s.scalar(select(func.count()).select_from(model)) or 0)


def _as(client, key: str) -> str:  # type: ignore[no-untyped-def]
    assert sign_in(client, key).status_code == 303
    return csrf_token(key)


def test_operator_degrades_a_sensor_and_the_schema_refuses_out_of_bounds(  # type: ignore[no-untyped-def]
        client, keys, aircraft) -> None:
    token = _as(client, keys["operator"])
    form = {"csrf": token, "aircraft": aircraft, "position": "WL1", "sensor": "lvdt",
            "kind": "noise", "value": "80", "onset_flight": "5"}
    r = client.post("/test-station/sensor-injections", data=form)
    assert r.status_code == 422 and 'id="sensor-error"' in r.text
    assert "noise factor must be above 1 and at most 50" in html.unescape(r.text)
    assert 'value="80"' in r.text  # the form keeps what was typed
    assert _count(client, SensorInjection) == 0
    # the server decides which kinds a sensor takes: the schema's message, not the page's
    r = client.post("/test-station/sensor-injections", data=form | {"kind": "stuck",
                                                                   "value": "0.01"})
    assert r.status_code == 422 and "stuck LVDT opens the position loop" in r.text
    r = client.post("/test-station/sensor-injections", data=form | {"value": "3"},
                    follow_redirects=False)
    assert r.status_code == 303 and r.headers["location"] == "/test-station"
    page = client.get("/test-station").text
    assert 'id="sensor-injection-1"' in page and "noise 3" in page
    r = client.post("/test-station/sensor-injections", data=form | {"value": "4"})
    assert r.status_code == 409 and "already has a live sensor injection" in r.text
    assert _count(client, SensorInjection) == 1


def test_operator_sets_a_condition_value_or_base(client, keys, aircraft) -> None:  # type: ignore[no-untyped-def]
    token = _as(client, keys["operator"])
    form = {"csrf": token, "aircraft": aircraft, "kind": "load_scale", "value": "4",
            "base": "", "onset_flight": "0"}
    r = client.post("/test-station/conditions", data=form)
    assert r.status_code == 422 and 'id="condition-error"' in r.text
    assert f"load_scale must be {condition_range('load_scale')}" in r.text
    r = client.post("/test-station/conditions", data=form | {"kind": "base", "value": "",
                                                            "base": "Atlantis"})
    assert r.status_code == 422 and "base must be one of Turin" in r.text
    assert _count(client, SimCondition) == 0
    for extra in ({"value": "1.5"}, {"kind": "base", "value": "", "base": "Abu Dhabi"}):
        r = client.post("/test-station/conditions", data=form | extra, follow_redirects=False)
        assert r.status_code == 303, r.text
    page = client.get("/test-station").text
    assert "load_scale 1.5" in page and "base Abu Dhabi" in page
    r = client.post("/test-station/conditions", data=form | {"value": "2"})
    assert r.status_code == 409 and "already has a live load_scale condition" in r.text
    assert _count(client, SimCondition) == 2


def test_the_hints_are_the_schemas_and_a_viewer_sees_no_forms(client, keys, aircraft) -> None:  # type: ignore[no-untyped-def]
    _as(client, keys["operator"])
    page = html.unescape(client.get("/test-station").text)
    assert 'id="sensor-form"' in page and 'id="condition-form"' in page
    assert SensorInjectionCreate.model_fields["value"].description in page
    assert condition_range("ambient_offset") == "at least -30 K and at most 30 K"
    assert condition_range("ambient_offset") in page
    client.cookies.clear()
    _as(client, keys["viewer"])
    page = client.get("/test-station").text
    assert 'id="sensor-form"' not in page and 'id="condition-form"' not in page
    assert 'id="no-inject"' in page


def test_forged_posts_are_refused_and_store_nothing(client, keys, aircraft) -> None:  # type: ignore[no-untyped-def]
    sensor = {"aircraft": aircraft, "position": "WT", "sensor": "current", "kind": "noise",
              "value": "3"}
    condition = {"aircraft": aircraft, "kind": "ambient_offset", "value": "10"}
    posts = (("/test-station/sensor-injections", sensor), ("/test-station/conditions",
                                                          condition))
    viewer = _as(client, keys["viewer"])
    for url, form in posts:
        assert client.post(url, data=form | {"csrf": viewer}).status_code == 403
    client.cookies.clear()
    operator = _as(client, keys["operator"])
    for url, form in posts:
        assert client.post(url, data=form).status_code == 403  # no token
        assert client.post(url, data=form | {"csrf": "0" * 64}).status_code == 403
        r = client.post(url, data=form | {"csrf": operator},
                        headers={"Origin": "https://evil.example"})
        assert r.status_code == 403
    assert _count(client, SensorInjection) == 0 and _count(client, SimCondition) == 0
