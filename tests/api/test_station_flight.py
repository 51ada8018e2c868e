"""The simulator's flight through the test station: GET /api/v1/test-station/plan (what is on an
aircraft for one flight, every kind at once) and PUT /api/v1/test-station/flights/{flight}
(every item's truth on it in one request; a failure back-fills the true RUL in one statement).
The runner's side: tests/sim/test_service_calls.py."""

from __future__ import annotations

import pytest
from fastapi.testclient import TestClient
from sqlalchemy import event

from tests.api.conftest import auth

API = "/api/v1/test-station"


def _schedule(client: TestClient, keys: dict[str, str], tail: str) -> dict[str, int]:
    """A fault from flight 3, a sensor injection from 1 (and a cancelled one), a condition
    from 5: their ids by kind."""
    op = auth(keys["operator"])
    made = {kind: client.post(f"{API}/{kind}", headers=op, json={"aircraft": tail, **body})
            for kind, body in (
                ("injections", {"position": "WT", "fault_mode": "DMD", "onset_flight": 3,
                                "time_to_failure_flights": 20}),
                ("sensor-injections", {"position": "WL1", "sensor": "lvdt", "kind": "noise",
                                       "value": 3, "onset_flight": 1}),
                ("conditions", {"kind": "load_scale", "value": 1.2, "onset_flight": 5}))}
    assert {r.status_code for r in made.values()} == {201}, [r.text for r in made.values()]
    gone = client.post(f"{API}/sensor-injections", headers=op, json={
        "aircraft": tail, "position": "WL2", "sensor": "current", "kind": "noise", "value": 2,
        "onset_flight": 0}).json()
    assert client.post(f"{API}/sensor-injections/{gone['id']}/cancel",
                       headers=op).status_code == 200
    return {kind: r.json()["id"] for kind, r in made.items()}


def _plan(client: TestClient, keys: dict[str, str], tail: str, flight: int) -> dict:  # type: ignore[type-arg]
    r = client.get(f"{API}/plan?aircraft={tail}&flight={flight}",
                   headers=auth(keys["viewer"]))
    assert r.status_code == 200, r.text
    return r.json()  # type: ignore[no-any-return]


def _ids(plan: dict) -> dict[str, list[int]]:  # type: ignore[type-arg]
    return {k: [i["id"] for i in plan[k]] for k in ("injections", "sensor_injections",
                                                     "conditions")}


def test_the_plan_holds_what_is_on_the_flight(client: TestClient, keys: dict[str, str],
                                              aircraft: str) -> None:
    ids = _schedule(client, keys, aircraft)
    first = _plan(client, keys, aircraft, 1)
    assert _ids(first) == {"injections": [], "sensor_injections": [ids["sensor-injections"]],
                           "conditions": []}
    assert set(first["aircraft"]["actuators"]) == {"WL1", "WL2", "WT"}
    assert first["sensor_injections"][0]["channels"] == ["WL1.x"]
    assert _ids(_plan(client, keys, aircraft, 5)) == {
        "injections": [ids["injections"]], "sensor_injections": [ids["sensor-injections"]],
        "conditions": [ids["conditions"]]}
    r = client.get(f"{API}/plan?aircraft=NOPE&flight=1", headers=auth(keys["viewer"]))
    assert r.status_code == 404
    r = client.get(f"{API}/plan?aircraft={aircraft}&flight=-1", headers=auth(keys["viewer"]))
    assert r.status_code == 422


def _report(client: TestClient, keys: dict[str, str], tail: str, n: int, ids: dict[str, int],
            **fault: object) -> dict:  # type: ignore[type-arg]
    r = client.put(f"{API}/flights/F{n:05d}", headers=auth(keys["operator"]), json={
        "aircraft": tail, "flight_number": n,
        "injections": [{"id": ids["injections"], "severity": 1e-3 * n,
                        "severity_norm": 0.01 * n, "planned_failure_flight": 23, **fault}],
        "sensor_injections": [{"id": ids["sensor-injections"], "applied": 3.0}],
        "conditions": [{"id": ids["conditions"], "applied": 1.2}]})
    assert r.status_code == 200, r.text
    return r.json()  # type: ignore[no-any-return]


def test_one_request_reports_a_flight_and_a_failure_marks_every_flight_at_once(
        client: TestClient, keys: dict[str, str], aircraft: str) -> None:
    ids = _schedule(client, keys, aircraft)
    viewer = auth(keys["viewer"])
    assert _report(client, keys, aircraft, 5, ids)["recorded"] == {
        "injections": 1, "sensor_injections": 1, "conditions": 1}
    fault = client.get(f"{API}/injections/{ids['injections']}", headers=viewer).json()
    assert (fault["status"], fault["planned_failure_flight"]) == ("active", 23)
    for kind in ("sensor-injections", "conditions"):
        item = client.get(f"{API}/{kind}/{ids[kind]}", headers=viewer).json()
        assert (item["status"], item["started_flight"]) == ("active", 5)
    _report(client, keys, aircraft, 5, ids)  # idempotent
    _report(client, keys, aircraft, 6, ids)

    engine = client.app.state.engine  # type: ignore[attr-defined]
    updates: list[str] = []

    def count(conn, cursor, statement, *args) -> None:  # type: ignore[no-untyped-def]
        if statement.lstrip().upper().startswith("UPDATE GROUND_TRUTH"):
            updates.append(statement)

    event.listen(engine, "before_cursor_execute", count)
    try:
        _report(client, keys, aircraft, 7, ids, failure_flight=8)
    finally:
        event.remove(engine, "before_cursor_execute", count)
    assert len(updates) == 1, updates  # flight 7 inserted, then one for every flight
    truth = client.get(f"{API}/injections/{ids['injections']}/ground-truth",
                       headers=viewer).json()
    assert [(t["flight_number"], t["true_rul_flights"]) for t in truth] == [
        (5, 3), (6, 2), (7, 1)]
    fault = client.get(f"{API}/injections/{ids['injections']}", headers=viewer).json()
    assert (fault["status"], fault["failure_flight"]) == ("failed", 8)
    unit = client.get(f"/api/v1/aircraft/{aircraft}", headers=viewer).json()["actuators"]["WT"]
    assert unit["failed_at_flight"] == 8
    # the failed fault is still on its unit for flight 7 (flown again after a restart)
    assert _ids(_plan(client, keys, aircraft, 7))["injections"] == [ids["injections"]]
    assert _ids(_plan(client, keys, aircraft, 8))["injections"] == []


@pytest.mark.parametrize(("change", "status", "code"), [
    ({"aircraft": "T002"}, 422, "not_on_aircraft"),
    ({"conditions": [{"id": 999, "applied": 1.0}]}, 404, "not_found"),
    ({"conditions": [{"id": 1, "applied": 1.0, "kind": "x"}]}, 422, "validation_error"),
    ({"sensor_injections": [{"id": 1}]}, 422, "validation_error"),
    ({"icing": []}, 422, "validation_error"),
])
def test_a_refused_report_stores_nothing(client: TestClient, keys: dict[str, str],
                                         aircraft: str, change: dict[str, object], status: int,
                                         code: str) -> None:
    ids = _schedule(client, keys, aircraft)
    client.post("/api/v1/aircraft", headers=auth(keys["admin"]), json={
        "tail": "T002", "base": "Turin",
        "actuators": {"WL1": "T002-WL1", "WL2": "T002-WL2", "WT": "T002-WT"}})
    body = {"aircraft": aircraft, "flight_number": 5,
            "sensor_injections": [{"id": ids["sensor-injections"], "applied": 3.0}],
            "conditions": [{"id": ids["conditions"], "applied": 1.2}], **change}
    r = client.put(f"{API}/flights/F00005", headers=auth(keys["operator"]), json=body)
    assert r.status_code == status and r.json()["error"]["code"] == code, r.text
    viewer = auth(keys["viewer"])
    for kind in ("sensor-injections", "conditions"):
        assert client.get(f"{API}/{kind}/{ids[kind]}/ground-truth", headers=viewer).json() == []
        assert client.get(f"{API}/{kind}/{ids[kind]}", headers=viewer).json()["status"] == (
            "pending")


def test_only_an_operator_reports_a_flight(client: TestClient, keys: dict[str, str],
                                           aircraft: str) -> None:
    body = {"aircraft": aircraft, "flight_number": 1}
    for role in ("viewer", "uploader", "maintainer"):
        r = client.put(f"{API}/flights/F00001", headers=auth(keys[role]), json=body)
        assert r.status_code == 403, role
    r = client.put(f"{API}/flights/F00001", headers=auth(keys["operator"]), json=body)
    assert r.status_code == 200 and r.json()["recorded"] == {
        "injections": 0, "sensor_injections": 0, "conditions": 0}
