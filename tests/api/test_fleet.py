"""Aircraft and actuator endpoints, roles, and the maintenance action."""

from __future__ import annotations

from fastapi.testclient import TestClient

from tests.api.conftest import auth
from tests.flightlog_factory import serials_for


def test_create_list_get_aircraft(client: TestClient, keys: dict[str, str]) -> None:
    body = {"tail": "I-EMA1", "base": "Turin", "actuators": serials_for("I-EMA1")}
    r = client.post("/api/v1/aircraft", json=body, headers=auth(keys["admin"]))
    assert r.status_code == 201
    assert set(r.json()["actuators"]) == {"WL1", "WL2", "WT"}
    assert r.json()["actuators"]["WT"]["serial"] == "SN-WT-I-EMA1"

    listing = client.get("/api/v1/aircraft", headers=auth(keys["viewer"])).json()
    assert listing["total"] == 1 and listing["items"][0]["tail"] == "I-EMA1"
    assert client.get("/api/v1/aircraft?base=Vancouver",
                      headers=auth(keys["viewer"])).json()["total"] == 0
    one = client.get("/api/v1/aircraft/I-EMA1", headers=auth(keys["viewer"]))
    assert one.status_code == 200 and one.json()["base"] == "Turin"


def test_aircraft_conflicts_and_validation(client: TestClient, keys: dict[str, str],
                                           aircraft: str) -> None:
    admin = auth(keys["admin"])
    again = client.post("/api/v1/aircraft", headers=admin,
                        json={"tail": aircraft, "base": "Turin", "actuators": serials_for("X")})
    assert again.status_code == 409 and again.json()["error"]["code"] == "aircraft_exists"
    reused = client.post("/api/v1/aircraft", headers=admin,
                         json={"tail": "T002", "base": "Turin", "actuators": serials_for(aircraft)})
    assert reused.status_code == 409 and reused.json()["error"]["code"] == "serial_in_use"
    bad = client.post("/api/v1/aircraft", headers=admin,
                      json={"tail": "../etc", "base": "Turin", "actuators": serials_for("Y")})
    assert bad.status_code == 422 and bad.json()["error"]["code"] == "validation_error"
    same = client.post("/api/v1/aircraft", headers=admin, json={
        "tail": "T003", "base": "Turin", "actuators": {"WL1": "A", "WL2": "A", "WT": "B"}})
    assert same.status_code == 422
    missing = client.get("/api/v1/aircraft/NOPE", headers=admin)
    assert missing.status_code == 404 and missing.json()["error"]["code"] == "not_found"


def test_roles_on_fleet_writes(client: TestClient, keys: dict[str, str]) -> None:
    body = {"tail": "T009", "base": "Turin", "actuators": serials_for("T009")}
    assert client.post("/api/v1/aircraft", json=body).status_code == 401
    assert client.post("/api/v1/aircraft", json=body,
                       headers=auth("hmsm_not-a-real-key")).status_code == 401
    for role in ("viewer", "uploader", "operator"):
        r = client.post("/api/v1/aircraft", json=body, headers=auth(keys[role]))
        assert r.status_code == 403, role
        assert r.json()["error"]["code"] == "forbidden"
    assert client.get("/api/v1/aircraft").status_code == 401


def test_actuators_and_replacement(client: TestClient, keys: dict[str, str], aircraft: str
                                   ) -> None:
    viewer, admin = auth(keys["viewer"]), auth(keys["admin"])
    acts = client.get(f"/api/v1/actuators?aircraft={aircraft}", headers=viewer).json()
    assert acts["total"] == 3
    wl1 = next(a for a in acts["items"] if a["position"] == "WL1")
    assert client.get(f"/api/v1/actuators/{wl1['id']}", headers=viewer).json()["serial"] == (
        wl1["serial"])

    path = f"/api/v1/actuators/{wl1['id']}/replace"
    body = {"new_serial": "SN-NEW", "work_order": "WO-1"}
    assert client.post(path, json=body, headers=viewer).status_code == 403
    assert client.post(path, json={"new_serial": "SN-NEW"}, headers=admin).status_code == 422
    r = client.post(path, json={**body, "note": "backlash"}, headers=admin)
    assert r.status_code == 201
    new = r.json()
    assert new["id"] != wl1["id"] and new["position"] == "WL1" and new["removed_at"] is None

    old = client.get(f"/api/v1/actuators/{wl1['id']}", headers=viewer).json()
    assert old["removed_at"] is not None and old["removal_note"] == "backlash"
    installed = client.get(f"/api/v1/aircraft/{aircraft}", headers=viewer).json()["actuators"]
    assert installed["WL1"]["serial"] == "SN-NEW"
    assert client.get("/api/v1/actuators?installed=false", headers=viewer).json()["total"] == 1
    twice = client.post(path, json={"new_serial": "SN-NEW2", "work_order": "WO-2"},
                        headers=admin)
    assert twice.status_code == 409
    taken = client.post(f"/api/v1/actuators/{new['id']}/replace",
                        json={"new_serial": installed["WT"]["serial"], "work_order": "WO-3"},
                        headers=admin)
    assert taken.status_code == 409
    assert client.get("/api/v1/actuators/99999", headers=viewer).status_code == 404


def test_key_administration(client: TestClient, keys: dict[str, str]) -> None:
    admin = auth(keys["admin"])
    assert client.get("/api/v1/keys", headers=auth(keys["viewer"])).status_code == 403
    created = client.post("/api/v1/keys", json={"name": "recorder", "role": "uploader"},
                          headers=admin)
    assert created.status_code == 201
    new_key = created.json()["key"]
    assert client.get("/api/v1/aircraft", headers=auth(new_key)).status_code == 200
    listing = client.get("/api/v1/keys", headers=admin).json()
    assert all("key" not in k and "key_hash" not in k for k in listing)
    revoked = client.post(f"/api/v1/keys/{created.json()['id']}/revoke", headers=admin)
    assert revoked.status_code == 200 and revoked.json()["revoked_at"]
    assert client.get("/api/v1/aircraft", headers=auth(new_key)).status_code == 401
    bad = client.post("/api/v1/keys", json={"name": "x", "role": "god"}, headers=admin)
    assert bad.status_code == 422


def test_health(client: TestClient, keys: dict[str, str]) -> None:
    assert client.get("/api/v1/health/live").json() == {"status": "ok"}
    ready = client.get("/api/v1/health/ready")
    assert ready.status_code == 200 and ready.json()["database"] == "ok"
    spec = client.get("/openapi.json", headers=auth(keys["viewer"])).json()
    assert spec["info"]["title"].startswith("EMA")
    assert client.get("/docs", headers=auth(keys["viewer"])).status_code == 200
