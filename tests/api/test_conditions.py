"""POST/GET /api/v1/test-station/conditions: bounds, roles, conflicts, cancel and ground truth
(the simulator's side: tests/sim/test_conditions.py; the runner's: tests/e2e/test_conditions.py)."""

from __future__ import annotations

import pytest
from fastapi.testclient import TestClient

from tests.api.conftest import auth

URL = "/api/v1/test-station/conditions"


def _body(tail: str, /, **over: object) -> dict[str, object]:
    return {"aircraft": tail, "kind": "ambient_offset", "value": 15, **over}


@pytest.mark.parametrize(("over", "says"), [
    ({"value": 30.5}, "ambient_offset must be at least -30 K and at most 30 K"),
    ({"value": -31}, "ambient_offset must be at least -30 K"),
    ({"value": "nan"}, "Input should be a valid number"),  # a string is no number
    ({"value": None}, "a ambient_offset condition needs a value"),
    ({"kind": "load_scale", "value": 0}, "load_scale must be above 0 and at most 3"),
    ({"kind": "load_scale", "value": 3.01}, "load_scale must be above 0 and at most 3"),
    ({"kind": "command_scale", "value": -1}, "command_scale must be above 0"),
    ({"kind": "load_offset", "value": 1001}, "load_offset must be at least -1000 N"),
    ({"kind": "base", "value": None, "base": "Paris"}, "base must be one of Turin, Vancouver"),
    ({"kind": "base", "value": 1, "base": "Turin"}, "takes a base, not a value"),
    ({"base": "Turin"}, "takes a value, not a base"),
    ({"kind": "humidity"}, "Input should be"),
    ({"onset_flight": -1}, "greater than or equal to 0"),
    ({"extra": 1}, "Extra inputs are not permitted"),
])
def test_out_of_bounds_is_a_422_that_says_why(client: TestClient, keys: dict[str, str],
                                              aircraft: str, over: dict[str, object],
                                              says: str) -> None:
    r = client.post(URL, headers=auth(keys["operator"]), json=_body(aircraft, **over))
    assert r.status_code == 422 and says in r.text, r.text


def test_roles_conflicts_list_cancel_and_truth(client: TestClient, keys: dict[str, str],
                                               aircraft: str) -> None:
    for role in ("viewer", "uploader", "maintainer"):
        r = client.post(URL, headers=auth(keys[role]), json=_body(aircraft))
        assert r.status_code == 403, (role, r.text)
    assert client.post(URL, json=_body(aircraft)).status_code == 401
    op, viewer = auth(keys["operator"]), auth(keys["viewer"])
    assert client.post(URL, headers=op, json=_body("NOPE")).status_code == 404
    hot = client.post(URL, headers=op, json=_body(aircraft, onset_flight=3))
    assert hot.status_code == 201, hot.text
    assert (hot.json()["status"], hot.json()["created_by"]) == ("pending", "test-operator")
    r = client.post(URL, headers=op, json=_body(aircraft, value=-10))
    assert r.status_code == 409 and r.json()["error"]["code"] == "condition_exists"
    assert "ambient_offset 15" in r.json()["error"]["message"]
    # conditions of other kinds compose with it; admins are operators too
    for body, key in ((_body(aircraft, kind="load_scale", value=1.5), op),
                      (_body(aircraft, kind="load_offset", value=-200), op),
                      (_body(aircraft, kind="command_scale", value=0.5), op),
                      (_body(aircraft, kind="base", value=None, base="Abu Dhabi"),
                       auth(keys["admin"]))):
        r = client.post(URL, headers=key, json=body)
        assert r.status_code == 201, r.text
    base = r.json()
    assert (base["base"], base["value"]) == ("Abu Dhabi", None)

    page = client.get(f"{URL}?aircraft={aircraft}&status=pending", headers=viewer).json()
    assert page["total"] == 5 and [i["kind"] for i in page["items"]][::4] == [
        "base", "ambient_offset"]
    assert client.get(f"{URL}?status=failed", headers=viewer).status_code == 422
    assert client.get(f"{URL}/999999", headers=viewer).status_code == 404
    hid = hot.json()["id"]
    assert client.post(f"{URL}/{hid}/cancel", headers=viewer).status_code == 403
    r = client.post(f"{URL}/{hid}/cancel", headers=op)
    assert r.status_code == 200 and r.json()["cancelled_at"] is not None
    assert client.post(f"{URL}/{hid}/cancel", headers=op).status_code == 409
    # cancelled, its kind is free again
    assert client.post(URL, headers=op, json=_body(aircraft, value=-10)).status_code == 201

    # ground truth is the sim worker's (operator) to write; the first report makes it active
    truth = {"flight": f"{aircraft}-F00004", "flight_number": 4, "applied": 31.5}
    bid = base["id"]
    assert client.put(f"{URL}/{bid}/ground-truth", headers=viewer,
                      json=truth).status_code == 403
    for _ in range(2):  # idempotent
        assert client.put(f"{URL}/{bid}/ground-truth", headers=op,
                          json=truth).status_code == 200
    assert client.get(f"{URL}/{bid}/ground-truth", headers=viewer).json() == [
        {**truth, "condition_id": bid}]
    doc = client.get(f"{URL}/{bid}", headers=viewer).json()
    assert (doc["status"], doc["started_flight"]) == ("active", 4)
    # a condition is the aircraft's: replacing a unit leaves it live
    wt = next(c["actuator_id"] for c in client.get("/api/v1/fleet/health", headers=viewer
                                                   ).json() if c["position"] == "WT")
    r = client.post(f"/api/v1/actuators/{wt}/replace", headers=auth(keys["maintainer"]),
                    json={"new_serial": "WT-NEW-1", "work_order": "WO-2026-0001"})
    assert r.status_code == 201, r.text
    assert client.get(f"{URL}/{bid}", headers=viewer).json()["status"] == "active"
