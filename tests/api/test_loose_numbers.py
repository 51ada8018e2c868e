"""Numbers as JSON means them (issue 57, "loose numbers"): every number field of a request body
refuses ``true`` and ``"1.5"`` (an SE fault injection with ``"severity": true`` was created at
severity 1.0, the maximum); every integer field takes ``174.0`` (the same JSON number as
``174``, which the schema's ``integer`` holds) and refuses ``true`` and ``"174"``; every row id
of a path or a query is bounded by its column in the schema, so that an id beyond 64 bits is a
validation 422 naming the parameter, never the database driver's words.

The fields and parameters are read from the app's own OpenAPI schema (and, for the dashboard,
its routes), so that a field added later is held to the same rule."""

from __future__ import annotations

import re
from collections.abc import Iterator
from typing import Any

from fastapi.routing import APIRoute
from fastapi.testclient import TestClient

from server.schemas import MAX_INT32
from server.web import routes as web_routes
from tests.api.conftest import auth

BIG = 442817151593597894656  # beyond 64 bits


def _resolve(doc: dict[str, Any], schema: dict[str, Any]) -> dict[str, Any]:
    while "$ref" in schema:
        schema = doc["components"]["schemas"][schema["$ref"].rsplit("/", 1)[1]]
    return schema


def _types(doc: dict[str, Any], schema: dict[str, Any]) -> set[str]:
    schema = _resolve(doc, schema)
    if "anyOf" in schema:
        return set().union(*(_types(doc, s) for s in schema["anyOf"]))
    return {schema["type"]} if "type" in schema else set()


def _fields(doc: dict[str, Any], schema: dict[str, Any], path: tuple[str, ...] = ()
            ) -> Iterator[tuple[tuple[str, ...], dict[str, Any]]]:
    """Every property of a body schema, nested objects' too: (path, its schema)."""
    schema = _resolve(doc, schema)
    for name, prop in schema.get("properties", {}).items():
        yield (*path, name), prop
        for option in [prop, *prop.get("anyOf", [])]:
            if _resolve(doc, option).get("properties"):
                yield from _fields(doc, option, (*path, name))


def _json_bodies(doc: dict[str, Any]) -> Iterator[tuple[str, str, dict[str, Any]]]:
    for template, item in doc["paths"].items():
        for method, op in item.items():
            body = op.get("requestBody", {}).get("content", {}).get("application/json")
            if body:
                # a path's ids and tails as any valid value: the body is validated with them
                yield method, re.sub(r"\{[^}]+\}", "1", template), body["schema"]


def _nested(path: tuple[str, ...], value: object) -> dict[str, Any]:
    body: Any = value
    for name in reversed(path):
        body = {name: body}
    return body


def _errors_at(r, loc: list[object]) -> list[dict[str, Any]]:  # type: ignore[no-untyped-def]
    assert r.status_code == 422, r.text[:300]
    return [e for e in r.json()["error"]["details"]["errors"] if e["loc"] == loc]


def test_every_number_field_of_a_body_refuses_true_and_strings(
        app, client: TestClient, keys: dict[str, str]) -> None:  # type: ignore[no-untyped-def]
    doc, admin = app.openapi(), auth(keys["admin"])
    checked = []
    for method, url, schema in _json_bodies(doc):
        for path, prop in _fields(doc, schema):
            if "number" not in _types(doc, prop):
                continue
            for value in (True, "1.5", "2"):
                r = client.request(method, url, headers=admin, json=_nested(path, value))
                errors = _errors_at(r, ["body", *path])
                assert [e["type"] for e in errors] == ["float_type"], (method, url, path, value,
                                                                        r.text[:300])
            checked.append((url, path))
    # severity; value of sensor injections and conditions; ground truth's severity and
    # severity_norm; what sensor injections and conditions applied
    assert len(checked) >= 7, checked


def test_every_integer_field_of_a_body_takes_174_0_and_refuses_true_and_strings(
        app, client: TestClient, keys: dict[str, str]) -> None:  # type: ignore[no-untyped-def]
    doc, admin = app.openapi(), auth(keys["admin"])
    checked = []
    for method, url, schema in _json_bodies(doc):
        for path, prop in _fields(doc, schema):
            if "integer" not in _types(doc, prop):
                continue
            bounded = next(s for s in [prop, *prop.get("anyOf", [])]
                           if _resolve(doc, s).get("type") == "integer")
            assert "minimum" in bounded and "maximum" in bounded, (url, path, prop)
            integral = float(bounded["minimum"])  # e.g. 10.0: within the field's bounds
            r = client.request(method, url, headers=admin, json=_nested(path, integral))
            if r.status_code == 422:
                assert _errors_at(r, ["body", *path]) == [], (method, url, path, r.text[:300])
            for value in (True, "174", 1.5):
                r = client.request(method, url, headers=admin, json=_nested(path, value))
                assert _errors_at(r, ["body", *path]), (method, url, path, value)
            checked.append((url, path))
    assert len(checked) >= 10, checked


def test_the_loose_numbers_of_the_issue_create_nothing_and_174_0_is_174(
        client: TestClient, keys: dict[str, str], aircraft: str) -> None:
    op = auth(keys["operator"])
    station = "/api/v1/test-station"
    se = {"aircraft": aircraft, "position": "WL1", "fault_mode": "SE"}
    assert client.post(f"{station}/injections", headers=op,
                       json={**se, "severity": True}).status_code == 422
    for value in (True, "1.5"):
        r = client.post(f"{station}/conditions", headers=op,
                        json={"aircraft": aircraft, "kind": "load_scale", "value": value})
        assert r.status_code == 422, r.text
    r = client.post(f"{station}/sensor-injections", headers=op, json={
        "aircraft": aircraft, "position": "WT", "sensor": "current", "kind": "noise",
        "value": "2"})
    assert r.status_code == 422, r.text
    for kind in ("injections", "conditions", "sensor-injections"):
        assert client.get(f"{station}/{kind}", headers=op).json()["items"] == [], kind
    r = client.post(f"{station}/injections", headers=op, json={**se, "onset_flight": 174.0})
    assert r.status_code == 201 and r.json()["onset_flight"] == 174, r.text


def _id_parameters(doc: dict[str, Any]) -> Iterator[tuple[str, str, dict[str, Any]]]:
    for template, item in doc["paths"].items():
        for method, op in item.items():
            for parameter in op.get("parameters", []):
                if parameter["name"] == "id" or parameter["name"].endswith("_id"):
                    yield method, template, parameter


def _url(template: str, name: str, where: str, value: int) -> str:
    url = re.sub(r"\{[^}]+\}", lambda m: str(value) if m.group(0) == f"{{{name}}}" else "1",
                 template)
    return f"{url}?{name}={value}" if where == "query" else url


def _refused_as_invalid(r, where: str, name: str) -> None:  # type: ignore[no-untyped-def]
    assert r.status_code == 422, r.text[:300]
    assert _errors_at(r, [where, name]), r.text[:300]
    assert "SQLite" not in r.text and "too large" not in r.text, r.text[:300]


def test_every_id_of_the_api_is_bounded_in_the_schema_and_refused_beyond(
        app, client: TestClient, keys: dict[str, str]) -> None:  # type: ignore[no-untyped-def]
    doc, admin = app.openapi(), auth(keys["admin"])
    checked = 0
    for method, template, parameter in _id_parameters(doc):
        name, where = parameter["name"], parameter["in"]
        schema = next(s for s in [parameter["schema"], *parameter["schema"].get("anyOf", [])]
                      if s.get("type") == "integer")
        assert (schema.get("minimum"), schema.get("maximum")) == (1, MAX_INT32), (template, name)
        for value in (BIG, 2**63, MAX_INT32 + 1, 0):
            r = client.request(method, _url(template, name, where, value), headers=admin)
            _refused_as_invalid(r, where, name)
        checked += 1
    assert checked >= 30, checked


def test_every_id_of_the_dashboard_is_refused_beyond_its_column(
        app, keys: dict[str, str]) -> None:  # type: ignore[no-untyped-def]
    signed_in = TestClient(app, cookies={"hmsm_session": keys["admin"]},
                           raise_server_exceptions=False)
    checked = 0
    for route in web_routes.router.routes:  # mounted at "/", outside the API's schema
        assert isinstance(route, APIRoute)
        for where, params in (("path", route.dependant.path_params),
                              ("query", route.dependant.query_params)):
            for param in params:
                if param.name != "id" and not param.name.endswith("_id"):
                    continue
                for method in route.methods:
                    r = signed_in.request(method, _url(route.path, param.name, where, BIG))
                    _refused_as_invalid(r, where, param.name)
                checked += 1
    assert checked >= 10, checked
