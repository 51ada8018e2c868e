"""Maintenance actions (replace, inspect / no fault found, defer), the audit trail, the failed
state and the inbox order by urgency bucket, through the API on the real app and database.

Alarm, state and health rows are written as the analysis writes them
(``server/services/analysis.py``): the chain itself needs a trained model and is tested end to
end elsewhere."""

from __future__ import annotations

from datetime import datetime, timedelta, timezone

from fastapi.testclient import TestClient
from sqlalchemy import select

from server.db import session_scope
from server.models import Actuator, ActuatorState, Aircraft, Alarm, Flight, HealthRecord
from server.phm.chain import ActuatorHealth
from server.phm.detection import DetectionState
from tests.api.conftest import auth
from tests.flightlog_factory import make_parquet, serials_for

PARQUET = {"Content-Type": "application/vnd.apache.parquet"}


def _upload(client: TestClient, keys: dict[str, str], tail: str, flight: str,
            serials: dict[str, str] | None = None):  # type: ignore[no-untyped-def]
    return client.post("/api/v1/flights", content=make_parquet(tail, flight, serials=serials),
                       headers={**PARQUET, **auth(keys["uploader"])})


def _seed(app, tail: str, position: str, *, mode: str = "MTWEAR", low: float | None = None,  # type: ignore[no-untyped-def]
          confidence: float = 0.99, flights_seen: int = 10) -> tuple[int, int]:
    """(actuator id, alarm id): an installed unit with a state, a health record and an alarm."""
    with session_scope(app.state.session_factory) as s:
        act = s.scalar(select(Actuator).join(Aircraft).where(
            Aircraft.tail == tail, Actuator.position == position, Actuator.removed_at.is_(None)))
        flight = s.scalar(select(Flight).where(Flight.tail == tail).limit(1))
        s.add(ActuatorState(actuator_id=act.id, flights_seen=flights_seen,
                            detection={"confidence": confidence}, fault_mode=mode))
        s.add(HealthRecord(actuator_id=act.id, flight_id=flight.id, flight_index=flights_seen,
                           confidence=confidence, alarm=True))
        alarm = Alarm(actuator_id=act.id, flight_id=flight.id, confidence=confidence,
                      fault_mode=mode, class_probability=0.9, features=[f"{position}.F_x"],
                      rul_median_flights=None if low is None else 2 * low,
                      rul_low_flights=low)
        s.add(alarm)
        s.flush()
        return act.id, alarm.id


def _as_cookie(client: TestClient, key: str, method: str, url: str, **kwargs):  # type: ignore[no-untyped-def]
    """A request with the dashboard's session cookie (and no Bearer key)."""
    client.cookies.set("hmsm_session", key)
    try:
        return client.request(method, url, **kwargs)
    finally:
        client.cookies.clear()


def _grid(client: TestClient, keys: dict[str, str]) -> dict[tuple[str, str], dict]:
    cells = client.get("/api/v1/fleet/health", headers=auth(keys["viewer"])).json()
    return {(c["tail"], c["position"]): c for c in cells}


def test_replace_starts_a_fresh_history_closes_alarms_and_ends_the_injection(  # type: ignore[no-untyped-def]
        app, client: TestClient, keys: dict[str, str], aircraft: str) -> None:
    assert _upload(client, keys, aircraft, "A1").status_code == 202
    old_id, alarm_id = _seed(app, aircraft, "WT", mode="BDO")
    op, station = auth(keys["maintainer"]), auth(keys["operator"])
    inj = client.post("/api/v1/test-station/injections", headers=station, json={
        "aircraft": aircraft, "position": "WT", "fault_mode": "BDO"}).json()
    client.post(f"/api/v1/test-station/injections/{inj['id']}/status", headers=station,
                json={"status": "active"})
    assert _grid(client, keys)[(aircraft, "WT")]["urgency"] == "replace_now"

    r = client.post(f"/api/v1/actuators/{old_id}/replace", headers=op,
                    json={"new_serial": "WT-NEW-1", "work_order": "WO-2026-0042",
                          "note": "open MOSFET leg"})
    assert r.status_code == 201, r.text
    new = r.json()
    assert new["serial"] == "WT-NEW-1" and new["failed_at_flight"] is None

    viewer = auth(keys["viewer"])
    alarm = next(a for a in client.get("/api/v1/alarms", headers=viewer).json()["items"]
                 if a["id"] == alarm_id)
    assert alarm["status"] == "closed" and alarm["resolution"] == "replaced"
    assert alarm["closed_by"] == "test-maintainer" and "WO-2026-0042" in alarm["note"]
    # the new unit: no health, no prognosis, no state: its next analysis starts from its own
    # first flights (a fresh baseline); the cell is healthy
    assert client.get(f"/api/v1/actuators/{new['id']}/health", headers=viewer).json() == []
    assert client.get(f"/api/v1/actuators/{new['id']}/prognoses", headers=viewer).json() == []
    with session_scope(app.state.session_factory) as s:
        assert s.get(ActuatorState, new["id"]) is None
    cell = _grid(client, keys)[(aircraft, "WT")]
    assert (cell["actuator_id"], cell["urgency"], cell["status"]) == (new["id"], "healthy",
                                                                      "green")
    # the injection ended with the unit: the simulator flies the new serial healthy
    inj = client.get(f"/api/v1/test-station/injections/{inj['id']}", headers=viewer).json()
    assert inj["status"] == "cancelled" and inj["cancelled_at"]
    # the next flights carry the new serial and are accepted; the old serial is refused
    serials = {**serials_for(aircraft), "WT": "WT-NEW-1"}
    assert _upload(client, keys, aircraft, "A2", serials).status_code == 202
    assert _upload(client, keys, aircraft, "A3").status_code == 422

    for actuator in (old_id, new["id"]):  # the trail is on both units
        trail = client.get(f"/api/v1/actuators/{actuator}/maintenance", headers=viewer).json()
        assert [(t["kind"], t["work_order"], t["performed_by"], t["new_actuator_id"],
                 t["closed_alarms"]) for t in trail] == [
            ("replace", "WO-2026-0042", "test-maintainer", new["id"], 1)]
        assert datetime.fromisoformat(trail[0]["performed_at"]) > datetime.now(
            timezone.utc) - timedelta(minutes=5)
    again = client.post(f"/api/v1/actuators/{old_id}/replace", headers=op,
                        json={"new_serial": "WT-NEW-2", "work_order": "WO-2026-0043"})
    assert again.status_code == 409 and again.json()["error"]["code"] == "already_removed"


def test_inspect_closes_as_false_alarm_and_keeps_monitoring(  # type: ignore[no-untyped-def]
        app, client: TestClient, keys: dict[str, str], aircraft: str) -> None:
    assert _upload(client, keys, aircraft, "A1").status_code == 202
    act_id, alarm_id = _seed(app, aircraft, "WL2", mode="MTEL")
    with session_scope(app.state.session_factory) as s:  # a latched detector, as stored
        health = ActuatorHealth(position="WL2", detection=DetectionState.new(
            "WL2", ["WL2.F_MTEL"]), flights_seen=10, alarm_index=8, fault_mode="MTEL",
            class_log_prob={"MTEL": -0.1})
        health.detection.reference = {"WL2.F_MTEL": [0.1, -0.2, 0.05]}
        health.detection.alarm, health.detection.alarm_flight = True, 8
        health.detection.alarm_features = ["WL2.F_MTEL"]
        s.get(ActuatorState, act_id).detection = {**health.to_dict(), "confidence": 0.99}
    admin, viewer = auth(keys["admin"]), auth(keys["viewer"])
    r = client.post(f"/api/v1/actuators/{act_id}/inspect", headers=admin,
                    json={"work_order": "AMM/27-51/113", "note": "grease fine"})
    assert r.status_code == 201, r.text
    action = r.json()
    assert (action["kind"], action["alarm_id"], action["performed_by"]) == (
        "inspect", alarm_id, "test-admin")
    closed = client.get("/api/v1/alarms?status=closed", headers=viewer).json()["items"]
    assert [(a["id"], a["resolution"]) for a in closed] == [(alarm_id, "no_fault_found")]
    # still installed and monitored, its history kept; nothing left to inspect
    unit = client.get(f"/api/v1/actuators/{act_id}", headers=viewer).json()
    assert unit["removed_at"] is None
    assert len(client.get(f"/api/v1/actuators/{act_id}/health", headers=viewer).json()) == 1
    assert _grid(client, keys)[(aircraft, "WL2")]["urgency"] == "healthy"
    with session_scope(app.state.session_factory) as s:  # re-armed: a new alarm can be raised
        rearmed = ActuatorHealth.from_dict(s.get(ActuatorState, act_id).detection)
    assert not rearmed.detection.alarm and rearmed.detection.alarm_features == []
    assert rearmed.fault_mode is None and rearmed.alarm_index is None
    assert rearmed.detection.reference == {"WL2.F_MTEL": [0.1, -0.2, 0.05]}  # same unit
    assert rearmed.flights_seen == 10
    again = client.post(f"/api/v1/actuators/{act_id}/inspect", headers=admin,
                        json={"work_order": "WO-99"})
    assert again.status_code == 409 and again.json()["error"]["code"] == "no_open_alarm"


def test_defer_downgrades_until_expiry_and_the_expiry_is_visible(  # type: ignore[no-untyped-def]
        app, client: TestClient, keys: dict[str, str], aircraft: str) -> None:
    assert _upload(client, keys, aircraft, "A1").status_code == 202
    act_id, alarm_id = _seed(app, aircraft, "WL1", mode="TTS", low=20.0, flights_seen=10)
    op, viewer = auth(keys["maintainer"]), auth(keys["viewer"])
    assert _grid(client, keys)[(aircraft, "WL1")]["urgency"] == "act_within"
    path = f"/api/v1/actuators/{act_id}/defer"
    bad = [({"work_order": "WO-1", "reason": "parts on order"}, 422),  # no bound
           ({"work_order": "x", "reason": "parts on order", "flights": 5}, 422),
           ({"work_order": "WO 1; DROP", "reason": "parts on order", "flights": 5}, 422),
           ({"work_order": "WO-1", "reason": "parts", "flights": 0}, 422),
           ({"work_order": "WO-1", "reason": "parts", "flights": True}, 422),
           ({"work_order": "WO-1", "reason": "parts", "until": "2020-01-01T00:00:00Z"}, 422),
           ({"work_order": "WO-1", "reason": "parts", "until": "2099-01-01T00:00:00"}, 422),
           ({"work_order": "WO-1", "reason": "parts", "flights": 5, "by": "x"}, 422)]
    for body, code in bad:
        r = client.post(path, headers=op, json=body)
        assert r.status_code == code and "error" in r.json(), (body, r.text)
    r = client.post(path, headers=op, json={"work_order": "MEL-27-01", "reason": "parts on order",
                                            "flights": 5})
    assert r.status_code == 201, r.text
    assert r.json()["defer_until_flight"] == 15
    alarm = client.get("/api/v1/alarms", headers=viewer).json()["items"][0]
    assert (alarm["urgency"], alarm["deferred_until_flight"], alarm["deferral_expired"]) == (
        "deferred", 15, False)
    assert _grid(client, keys)[(aircraft, "WL1")]["status"] == "grey"

    with session_scope(app.state.session_factory) as s:  # five more flights analysed
        s.get(ActuatorState, act_id).flights_seen = 15
    alarm = client.get("/api/v1/alarms", headers=viewer).json()["items"][0]
    assert (alarm["id"], alarm["urgency"], alarm["deferral_expired"]) == (
        alarm_id, "act_within", True)
    assert _grid(client, keys)[(aircraft, "WL1")]["status"] == "amber"
    page = _as_cookie(client, keys["viewer"], "GET", f"/actuators/{act_id}")
    assert "deferral of alarm" in page.text and "has expired" in page.text

    until = (datetime.now(timezone.utc) + timedelta(days=3)).isoformat()
    r = client.post(path, headers=op, json={"work_order": "MEL-27-02", "reason": "next A-check",
                                            "until": until})
    assert r.status_code == 201
    assert client.get("/api/v1/alarms", headers=viewer).json()["items"][0]["urgency"] == (
        "deferred")
    trail = client.get(f"/api/v1/actuators/{act_id}/maintenance", headers=viewer).json()
    assert [(t["kind"], t["work_order"], t["performed_by"]) for t in trail] == [
        ("defer", "MEL-27-01", "test-maintainer"), ("defer", "MEL-27-02", "test-maintainer")]


def test_failure_is_a_state_until_replaced(  # type: ignore[no-untyped-def]
        app, client: TestClient, keys: dict[str, str], aircraft: str) -> None:
    assert _upload(client, keys, aircraft, "A1").status_code == 202
    act_id, _ = _seed(app, aircraft, "WT", mode="TTS", low=300.0)
    op, viewer = auth(keys["maintainer"]), auth(keys["viewer"])
    station = auth(keys["operator"])
    inj = client.post("/api/v1/test-station/injections", headers=station, json={
        "aircraft": aircraft, "position": "WT", "fault_mode": "TTS",
        "time_to_failure_flights": 60}).json()
    path = f"/api/v1/test-station/injections/{inj['id']}/status"
    client.post(path, headers=station, json={"status": "active"})
    assert _grid(client, keys)[(aircraft, "WT")]["urgency"] == "monitor"
    assert client.post(path, headers=station, json={"status": "failed", "failure_flight": 57}
                       ).status_code == 200
    unit = client.get(f"/api/v1/actuators/{act_id}", headers=viewer).json()
    assert unit["failed_at_flight"] == 57 and unit["failed_at"]
    cell = _grid(client, keys)[(aircraft, "WT")]
    assert (cell["status"], cell["urgency"], cell["failed_at_flight"]) == ("red", "replace_now",
                                                                           57)
    # a falling severity estimate, an RUL climbing back: the unit stays failed
    with session_scope(app.state.session_factory) as s:
        s.scalar(select(Alarm).where(Alarm.actuator_id == act_id)).rul_low_flights = 116.0
    assert _grid(client, keys)[(aircraft, "WT")]["status"] == "red"
    page = _as_cookie(client, keys["viewer"], "GET", f"/actuators/{act_id}")
    assert "Failed at flight 57" in page.text
    for action, body in (("inspect", {"work_order": "WO-5"}),
                         ("defer", {"work_order": "WO-5", "reason": "later", "flights": 3})):
        r = client.post(f"/api/v1/actuators/{act_id}/{action}", headers=op, json=body)
        assert r.status_code == 409 and r.json()["error"]["code"] == "actuator_failed"
    new = client.post(f"/api/v1/actuators/{act_id}/replace", headers=op,
                      json={"new_serial": "WT-NEW", "work_order": "WO-6"}).json()
    assert new["failed_at_flight"] is None
    assert _grid(client, keys)[(aircraft, "WT")]["status"] == "green"


def test_inbox_and_grid_follow_the_urgency_bucket(  # type: ignore[no-untyped-def]
        app, client: TestClient, keys: dict[str, str], aircraft: str) -> None:
    admin = auth(keys["admin"])
    assert client.post("/api/v1/aircraft", headers=admin, json={
        "tail": "T002", "base": "Turin", "actuators": serials_for("T002")}).status_code == 201
    for tail in (aircraft, "T002"):
        assert _upload(client, keys, tail, "A1").status_code == 202
    # a confident false alarm, an actuator truly 40 flights from failure, a BDO
    _seed(app, aircraft, "WL1", mode="MTEL", low=400.0, confidence=0.999)
    _seed(app, aircraft, "WT", mode="TTS", low=40.0, confidence=0.90)
    _seed(app, "T002", "WL2", mode="BDO", confidence=0.80)
    _seed(app, "T002", "WT", mode="DMD", low=12.0, confidence=0.85)
    items = client.get("/api/v1/alarms?status=open", headers=auth(keys["viewer"])).json()[
        "items"]
    assert [(a["aircraft"], a["position"], a["urgency"], a["act_within_flights"])
            for a in items] == [("T002", "WL2", "replace_now", None),
                                ("T002", "WT", "act_within", 12),
                                (aircraft, "WT", "act_within", 40),
                                (aircraft, "WL1", "monitor", None)]
    assert items[1]["urgency_label"] == "act within 12 flights"
    grid = _grid(client, keys)
    assert [grid[k]["status"] for k in (("T002", "WL2"), ("T002", "WT"), (aircraft, "WT"),
                                         (aircraft, "WL1"), (aircraft, "WL2"))] == [
        "red", "amber", "amber", "yellow", "green"]
    page = _as_cookie(client, keys["viewer"], "GET", "/alarms").text
    assert page.index("alarm-") and "act within 12 flights" in page and "%.3f" not in page


def test_maintenance_roles_and_cookie_csrf(  # type: ignore[no-untyped-def]
        app, client: TestClient, keys: dict[str, str], aircraft: str) -> None:
    assert _upload(client, keys, aircraft, "A1").status_code == 202
    act_id, _ = _seed(app, aircraft, "WL1")
    bodies = {"replace": {"new_serial": "X-1", "work_order": "WO-1"},
              "inspect": {"work_order": "WO-1"},
              "defer": {"work_order": "WO-1", "reason": "parts", "flights": 2}}
    for action, body in bodies.items():
        url = f"/api/v1/actuators/{act_id}/{action}"
        assert client.post(url, json=body).status_code == 401, action
        for role in ("viewer", "uploader", "operator"):
            r = client.post(url, json=body, headers=auth(keys[role]))
            assert r.status_code == 403 and "maintainer" in r.json()["error"]["message"], role
        r = _as_cookie(client, keys["maintainer"], "POST", url, json=body)
        assert r.status_code == 403 and r.json()["error"]["code"] == "csrf_mismatch", action
    assert client.get(f"/api/v1/actuators/{act_id}/maintenance",
                      headers=auth(keys["viewer"])).json() == []
    assert client.get("/api/v1/actuators/9999/maintenance",
                      headers=auth(keys["viewer"])).status_code == 404
