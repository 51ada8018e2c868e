"""Concurrent fault injections at the test station: a second live fault on another actuator of
the aircraft, or of another mode on the same actuator, is accepted; the same mode on the same
actuator is a 409; every live one is listed and in the simulator's flight plan."""

from __future__ import annotations

from fastapi.testclient import TestClient

from tests.api.conftest import auth

URL = "/api/v1/test-station/injections"


def _inject(client: TestClient, op: dict[str, str], aircraft: str, position: str, mode: str,
            **extra: object):  # type: ignore[no-untyped-def]
    return client.post(URL, headers=op, json={"aircraft": aircraft, "position": position,
                                              "fault_mode": mode, "onset_flight": 2, **extra})


def test_a_second_fault_elsewhere_or_of_another_mode_is_accepted_the_same_one_is_a_409(
        client: TestClient, keys: dict[str, str], aircraft: str) -> None:
    op = auth(keys["operator"])
    first = _inject(client, op, aircraft, "WT", "TTS", time_to_failure_flights=40)
    other_actuator = _inject(client, op, aircraft, "WL1", "TTS", time_to_failure_flights=60)
    other_mode = _inject(client, op, aircraft, "WT", "DMD", time_to_failure_flights=80)
    assert [r.status_code for r in (first, other_actuator, other_mode)] == [201, 201, 201]
    again = _inject(client, op, aircraft, "WT", "TTS", time_to_failure_flights=20)
    assert again.status_code == 409, again.text
    error = again.json()["error"]
    assert error["code"] == "injection_exists"
    assert error["details"]["injection_id"] == first.json()["id"]
    assert f"{aircraft} WT already has a live TTS injection" in error["message"]

    viewer = auth(keys["viewer"])
    listed = client.get(f"{URL}?aircraft={aircraft}", headers=viewer).json()
    assert listed["total"] == 3
    assert {(i["position"], i["fault_mode"], i["status"]) for i in listed["items"]} == {
        ("WT", "TTS", "pending"), ("WL1", "TTS", "pending"), ("WT", "DMD", "pending")}
    plan = client.get(f"/api/v1/test-station/plan?aircraft={aircraft}&flight=2",
                      headers=op).json()
    assert [i["id"] for i in plan["injections"]] == sorted(
        r.json()["id"] for r in (first, other_actuator, other_mode))

    # cancelled, its slot is free again; the others stay live
    assert client.post(f"{URL}/{first.json()['id']}/cancel", headers=op).status_code == 200
    assert _inject(client, op, aircraft, "WT", "TTS").status_code == 201
    assert client.get(f"{URL}?aircraft={aircraft}&status=pending",
                      headers=viewer).json()["total"] == 3


def test_replacing_a_unit_ends_every_injection_on_it_and_no_other(
        client: TestClient, keys: dict[str, str], aircraft: str) -> None:
    op = auth(keys["operator"])
    on_wt = [_inject(client, op, aircraft, "WT", m, time_to_failure_flights=50).json()["id"]
             for m in ("MTEL", "MTWEAR")]
    on_wl2 = _inject(client, op, aircraft, "WL2", "MTEL", time_to_failure_flights=50).json()
    unit = client.get(f"/api/v1/aircraft/{aircraft}", headers=op).json()["actuators"]["WT"]
    r = client.post(f"/api/v1/actuators/{unit['id']}/replace", headers=auth(keys["maintainer"]),
                    json={"new_serial": "WT-NEW-1", "work_order": "WO-2026-0200"})
    assert r.status_code == 201, r.text
    status = {i["id"]: i["status"] for i in client.get(
        f"{URL}?aircraft={aircraft}", headers=op).json()["items"]}
    assert [status[i] for i in on_wt] == ["cancelled", "cancelled"]
    assert status[on_wl2["id"]] == "pending"
