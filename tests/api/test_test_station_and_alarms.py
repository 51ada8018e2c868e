"""Test-station injections and ground truth; the alarm workflow and maintenance closing alarms."""

from __future__ import annotations

from fastapi.testclient import TestClient

from server.db import session_scope
from server.models import Actuator, Alarm, Flight
from tests.api.conftest import auth
from tests.flightlog_factory import make_parquet


def test_injection_lifecycle_and_roles(client: TestClient, keys: dict[str, str], aircraft: str
                                       ) -> None:
    body = {"aircraft": aircraft, "position": "WL1", "fault_mode": "MTWEAR",
            "onset_flight": 3, "time_to_failure_flights": 200}
    assert client.post("/api/v1/test-station/injections", json=body).status_code == 401
    for role in ("viewer", "uploader"):
        r = client.post("/api/v1/test-station/injections", json=body, headers=auth(keys[role]))
        assert r.status_code == 403, role
    op = auth(keys["operator"])
    r = client.post("/api/v1/test-station/injections", json=body, headers=op)
    assert r.status_code == 201, r.text
    inj = r.json()
    assert inj["status"] == "pending" and inj["created_by"] == "test-operator"
    again = client.post("/api/v1/test-station/injections", json=body, headers=op)
    assert again.status_code == 409 and again.json()["error"]["code"] == "injection_exists"

    path = f"/api/v1/test-station/injections/{inj['id']}"
    active = client.post(path + "/status", json={"status": "active",
                                                 "planned_failure_flight": 203}, headers=op)
    assert active.json()["status"] == "active"
    assert active.json()["planned_failure_flight"] == 203
    gt = {"flight": "F00005", "flight_number": 5, "severity": 3e-5, "severity_norm": 0.1,
          "true_rul_flights": 180}
    assert client.put(path + "/ground-truth", json=gt, headers=op).status_code == 200
    assert client.put(path + "/ground-truth", json={**gt, "severity_norm": 0.11},
                      headers=op).status_code == 200  # idempotent upsert
    truth = client.get(path + "/ground-truth", headers=auth(keys["viewer"])).json()
    assert len(truth) == 1 and truth[0]["severity_norm"] == 0.11
    assert client.put(path + "/ground-truth", json=gt,
                      headers=auth(keys["viewer"])).status_code == 403

    listed = client.get("/api/v1/test-station/injections?status=active",
                        headers=auth(keys["viewer"])).json()
    assert listed["total"] == 1 and listed["items"][0]["aircraft"] == aircraft
    assert client.post(path + "/cancel", headers=auth(keys["viewer"])).status_code == 403
    cancelled = client.post(path + "/cancel", headers=op)
    assert cancelled.json()["status"] == "cancelled" and cancelled.json()["cancelled_at"]
    assert client.post(path + "/cancel", headers=op).status_code == 409


def test_a_time_to_failure_outside_the_models_training_spans_is_accepted_with_a_warning(
        client: TestClient, keys: dict[str, str], aircraft: str, active_model: None,
        shipped_model) -> None:  # type: ignore[no-untyped-def]
    low, high = shipped_model[1]["campaign"]["spans_flights"]["MTEL"]
    op = auth(keys["operator"])
    body = {"aircraft": aircraft, "position": "WT", "fault_mode": "MTEL"}
    inside = client.post("/api/v1/test-station/injections", headers=op,
                         json={**body, "time_to_failure_flights": (low + high) // 2})
    assert inside.status_code == 201 and inside.json()["warnings"] == []
    client.post(f"/api/v1/test-station/injections/{inside.json()['id']}/cancel", headers=op)
    short = client.post("/api/v1/test-station/injections", headers=op,
                        json={**body, "time_to_failure_flights": max(10, low // 3)})
    assert short.status_code == 201, short.text
    (warning,) = short.json()["warnings"]
    assert f"{low}-{high} flights" in warning and "extrapolation" in warning


def test_injection_validation(client: TestClient, keys: dict[str, str], aircraft: str) -> None:
    op = auth(keys["operator"])
    cases = [
        ({"aircraft": aircraft, "position": "WT", "fault_mode": "REWEAR"}, 422),
        ({"aircraft": aircraft, "position": "WL1", "fault_mode": "XYZ"}, 422),
        ({"aircraft": aircraft, "position": "WL1", "fault_mode": "SE",
          "time_to_failure_flights": 100}, 422),
        ({"aircraft": aircraft, "position": "WL1", "fault_mode": "TTS", "severity": 0.5}, 422),
        ({"aircraft": "NOPE", "position": "WL1", "fault_mode": "TTS"}, 404),
        ({"aircraft": aircraft, "position": "XX", "fault_mode": "TTS"}, 422),
    ]
    for body, code in cases:
        r = client.post("/api/v1/test-station/injections", json=body, headers=op)
        assert r.status_code == code, (body, r.text)
        assert "error" in r.json()


def _alarm(app, tail: str, position: str) -> int:  # type: ignore[no-untyped-def]
    """An alarm row as the pipeline writes it (the pipeline itself is tested end to end)."""
    from sqlalchemy import select

    with session_scope(app.state.session_factory) as s:
        act = s.scalar(select(Actuator).where(Actuator.position == position,
                                              Actuator.removed_at.is_(None)))
        flight = s.scalar(select(Flight).limit(1))
        alarm = Alarm(actuator_id=act.id, flight_id=flight.id, confidence=0.99,
                      fault_mode="MTWEAR", class_probability=0.9, features=["WL1.F_MTWEAR"],
                      rul_median_flights=40.0)
        s.add(alarm)
        s.flush()
        return alarm.id


def test_alarm_workflow_and_maintenance(app, client: TestClient, keys: dict[str, str],  # type: ignore[no-untyped-def]
                                        aircraft: str) -> None:
    up = client.post("/api/v1/flights", content=make_parquet(aircraft, "A1"), headers={
        "Content-Type": "application/vnd.apache.parquet", **auth(keys["uploader"])})
    assert up.status_code == 202
    alarm_id = _alarm(app, aircraft, "WL1")
    viewer, admin = auth(keys["viewer"]), auth(keys["admin"])
    inbox = client.get("/api/v1/alarms?status=open", headers=viewer).json()
    assert inbox["total"] == 1
    item = inbox["items"][0]
    # a wear alarm without a low RUL quantile is watched (server/services/urgency.py)
    assert item["urgency"] == "monitor" and "priority" not in item
    grid = {c["position"]: c for c in client.get("/api/v1/fleet/health", headers=viewer).json()}
    assert grid["WL1"]["status"] == "yellow" and grid["WT"]["status"] == "green"

    path = f"/api/v1/alarms/{alarm_id}"
    assert client.post(path + "/acknowledge", json={}, headers=viewer).status_code == 403
    ack = client.post(path + "/acknowledge", json={"note": "inspect at next A-check"},
                      headers=admin).json()
    assert ack["status"] == "acknowledged" and ack["acknowledged_by"] == "test-admin"
    assert client.post(path + "/acknowledge", json={}, headers=admin).status_code == 409

    actuator_id = grid["WL1"]["actuator_id"]
    new = client.post(f"/api/v1/actuators/{actuator_id}/replace",
                      json={"new_serial": "SN-REPL", "work_order": "WO-7", "note": "worn screw"},
                      headers=admin)
    assert new.status_code == 201
    closed = client.get("/api/v1/alarms?status=closed", headers=viewer).json()["items"][0]
    assert closed["closed_by"] == "test-admin" and "SN-REPL" in closed["note"]
    assert closed["resolution"] == "replaced"
    assert client.get(f"/api/v1/actuators/{new.json()['id']}/health",
                      headers=viewer).json() == []
    assert client.get("/api/v1/alarms/99999/close", headers=admin).status_code == 405
    assert client.post("/api/v1/alarms/99999/close", json={}, headers=admin).status_code == 404
