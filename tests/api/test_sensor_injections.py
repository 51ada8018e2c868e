"""POST/GET /api/v1/test-station/sensor-injections: bounds, roles, conflicts and cancel (the
simulator's side: tests/sim/test_sensor_injections.py)."""

from __future__ import annotations

import pytest
from fastapi.testclient import TestClient

from tests.api.conftest import auth

URL = "/api/v1/test-station/sensor-injections"


def _body(tail: str, /, **over: object) -> dict[str, object]:
    return {"aircraft": tail, "position": "WT", "sensor": "lvdt", "kind": "noise",
            "value": 3, **over}


@pytest.mark.parametrize("over", [
    {"value": 1.0}, {"value": 0.5}, {"value": 51}, {"value": "nan"}, {"value": None},
    {"kind": "drift", "sensor": "current", "value": 1e-6}, {"kind": "drift", "value": 0},
    {"kind": "drift", "value": 2e-3}, {"kind": "quantisation", "value": 2.0**-20},
    {"kind": "quantisation", "sensor": "voltage", "value": 51}, {"kind": "stuck"},
    {"kind": "stuck", "value": 0.0}, {"kind": "clipped", "sensor": "resolver", "value": 1},
    {"kind": "clipped", "sensor": "current", "value": 0}, {"kind": "clipped",
                                                          "sensor": "current", "value": 65},
    {"kind": "stuck", "sensor": "voltage", "value": -513}, {"kind": "stuck", "sensor":
                                                             "resolver", "value": 3.2},
    {"kind": "noisy"},
    {"sensor": "x"}, {"position": "WL3"}, {"onset_flight": -1}, {"onset_flight": "2"},
    {"extra": 1}, {"aircraft": "bad tail!"},
])
def test_out_of_bounds_is_a_422(client: TestClient, keys: dict[str, str], aircraft: str,
                                over: dict[str, object]) -> None:
    r = client.post(URL, headers=auth(keys["operator"]), json=_body(aircraft, **over))
    assert r.status_code == 422, r.text


def test_position_sensors_stuck_or_clipped_say_why_or_fly(
        client: TestClient, keys: dict[str, str], aircraft: str) -> None:
    op = auth(keys["operator"])
    for kind in ("stuck", "clipped"):
        r = client.post(URL, headers=op, json=_body(aircraft, kind=kind, value=0.001))
        assert r.status_code == 422 and "end stops" in r.text, r.text
    r = client.post(URL, headers=op, json=_body(aircraft, sensor="resolver", kind="clipped",
                                                value=1))
    assert r.status_code == 422 and "never saturates" in r.text, r.text
    r = client.post(URL, headers=op, json=_body(aircraft, sensor="resolver", kind="stuck",
                                                value=-0.5))
    assert r.status_code == 201 and r.json()["channels"] == ["WT.theta"], r.text


def test_roles_conflicts_list_and_cancel(client: TestClient, keys: dict[str, str],
                                         aircraft: str) -> None:
    for role in ("viewer", "uploader", "maintainer"):
        r = client.post(URL, headers=auth(keys[role]), json=_body(aircraft))
        assert r.status_code == 403, (role, r.text)
    assert client.post(URL, json=_body(aircraft)).status_code == 401
    assert client.post(URL, headers=auth(keys["operator"]),
                       json=_body("NOPE")).status_code == 404
    op = auth(keys["operator"])
    first = client.post(URL, headers=op, json=_body(aircraft)).json()
    r = client.post(URL, headers=op, json=_body(aircraft, kind="drift", value=-1e-6))
    assert r.status_code == 409 and r.json()["error"]["code"] == "sensor_injection_exists"
    for body in (_body(aircraft, position="WL1", sensor="current", kind="stuck", value=0),
                 _body(aircraft, position="WL2", sensor="voltage", kind="clipped", value=20)):
        r = client.post(URL, headers=op, json=body)
        assert r.status_code == 201, r.text
    # another sensor of the same actuator, and a fault on it, may fly beside it
    step = client.post(URL, headers=op, json=_body(aircraft, sensor="current",
                                                   kind="quantisation", value=0.25))
    assert step.status_code == 201 and step.json()["channels"] == ["WT.ia", "WT.ib", "WT.ic"]
    assert client.post("/api/v1/test-station/injections", headers=op, json={
        "aircraft": aircraft, "position": "WT", "fault_mode": "SE"}).status_code == 201

    viewer = auth(keys["viewer"])
    page = client.get(f"{URL}?aircraft={aircraft}&status=pending", headers=viewer).json()
    assert page["total"] == 4 and [i["id"] for i in page["items"]][::3] == [step.json()["id"],
                                                                            first["id"]]
    assert client.get(f"{URL}?status=failed", headers=viewer).status_code == 422
    assert client.get(f"{URL}/999999", headers=viewer).status_code == 404
    assert client.post(f"{URL}/{first['id']}/cancel", headers=viewer).status_code == 403
    r = client.post(f"{URL}/{first['id']}/cancel", headers=op)
    assert r.status_code == 200 and r.json()["cancelled_at"] is not None
    assert client.post(f"{URL}/{first['id']}/cancel", headers=op).status_code == 409
    # ground truth is the sim worker's (operator) to write
    truth = {"flight": "F1", "flight_number": 1, "applied": 0.25}
    sid = step.json()["id"]
    assert client.put(f"{URL}/{sid}/ground-truth", headers=viewer,
                      json=truth).status_code == 403
    assert client.put(f"{URL}/{sid}/ground-truth", headers=op, json=truth).status_code == 200
    assert client.get(f"{URL}/{sid}", headers=viewer).json()["status"] == "active"
    # replacing the actuator ends its sensor injections: the new unit's sensors are sound
    wt = next(c["actuator_id"] for c in client.get("/api/v1/fleet/health", headers=viewer
                                                   ).json() if c["position"] == "WT")
    r = client.post(f"/api/v1/actuators/{wt}/replace", headers=auth(keys["maintainer"]),
                    json={"new_serial": "WT-NEW-1", "work_order": "WO-2026-0001"})
    assert r.status_code == 201, r.text
    assert client.get(f"{URL}/{sid}", headers=viewer).json()["status"] == "cancelled"
