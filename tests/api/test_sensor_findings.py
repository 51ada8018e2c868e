"""Sensor advisories end to end: a flight flown with a noisier LVDT, uploaded and analysed by
the real worker, gives a sensor finding on that channel in the API (the actuator's findings,
the fleet grid) and on the actuator's page; a flight of the same aircraft as rigged gives
none. A flight flown far outside the conditions the model was designed on is named with the
condition and its design range, its features set aside, and raises no alarm."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from fastapi.testclient import TestClient

from server.config import Settings
from server.flightlog import write_parquet
from server.jobs.worker import Worker
from sim_worker.campaign import fleet_for
from sim_worker.conditions import NO_CONDITIONS, Conditions
from sim_worker.faults import healthy
from sim_worker.flight import simulate_flight
from tests.api.conftest import auth
from tests.flightlog_factory import serials_for
from tests.web.test_pages import sign_in

PARQUET = {"Content-Type": "application/vnd.apache.parquet"}


def _flight(tail: str, code: str, index: int, sensor_faults: tuple[str, ...],
            conditions: Conditions = NO_CONDITIONS) -> bytes:
    """A 60 s flight of the verification fleet's first aircraft, as downloaded by ``tail``."""
    aircraft = fleet_for("verification", 2, sensor_faults=sensor_faults)[0]
    log, _ = simulate_flight(aircraft, healthy(), index, np.random.default_rng(index),
                             duration_s=60.0, conditions=conditions)
    meta = replace(log.metadata, aircraft=tail, flight=code,
                   actuator_serials=serials_for(tail))
    return write_parquet(replace(log, metadata=meta))


def _analyse(client: TestClient, keys: dict[str, str], settings: Settings, data: bytes) -> int:
    r = client.post("/api/v1/flights", content=data,
                    headers={**PARQUET, **auth(keys["uploader"])})
    assert r.status_code == 202, r.text
    worker = Worker(settings)
    try:
        assert worker.run_once()
    finally:
        worker.engine.dispose()
    flight_id = int(r.json()["id"])
    status = client.get(f"/api/v1/flights/{flight_id}", headers=auth(keys["viewer"])).json()
    assert status["status"] == "analyzed", status
    return flight_id


def test_a_noisier_lvdt_is_a_sensor_finding_not_an_alarm(
        app, client: TestClient, keys: dict[str, str], aircraft: str, settings: Settings,
        active_model: None) -> None:  # type: ignore[no-untyped-def]
    viewer = auth(keys["viewer"])
    cells = {c["position"]: c for c in client.get("/api/v1/fleet/health", headers=viewer).json()}

    _analyse(client, keys, settings, _flight(aircraft, "F1", 1, ()))
    wt = cells["WT"]["actuator_id"]
    assert client.get(f"/api/v1/actuators/{wt}/sensor-findings", headers=viewer).json() == []

    noisy_id = _analyse(client, keys, settings, _flight(aircraft, "F2", 2, ("WT.lvdt:noise=3",)))
    found = client.get(f"/api/v1/actuators/{wt}/sensor-findings", headers=viewer).json()
    assert [f["flight_id"] for f in found] == [noisy_id]
    findings = found[0]["findings"]
    # the noisy LVDT alone is named (its offset figure, noisier too, may leave its band)
    assert {(f["channel"], f["sensor"]) for f in findings} == {("WT.x", "lvdt")}
    [finding] = [f for f in findings if f["metric"] == "noise"]
    assert finding["value"] > 2 * finding["high"] / 1.3  # about 3x the healthy floor
    # the features that read the LVDT are judged with a widened scatter, none set aside
    assert found[0]["set_aside"] == [] and set(found[0]["widened"]) <= {
        "WT.F_MTEL", "WT.F_MTWEAR"}
    for p in ("WL1", "WL2"):
        other = cells[p]["actuator_id"]
        assert client.get(f"/api/v1/actuators/{other}/sensor-findings",
                          headers=viewer).json() == []

    # every analysed flight keeps its channels' figures beside its features
    health = client.get(f"/api/v1/actuators/{wt}/health", headers=viewer).json()
    floors = [h["scores"]["quality"]["WT.x"]["noise"] for h in health]
    assert floors[1] > 2.5 * floors[0] and set(health[0]["scores"]["quality"]) == {
        f"WT.{c}" for c in ("ia", "ib", "ic", "va", "vb", "vc", "theta", "x", "i_sum", "v_sum")}

    grid = {c["position"]: c for c in client.get("/api/v1/fleet/health", headers=viewer).json()}
    assert {f["channel"] for f in grid["WT"]["sensor_findings"]} == {"WT.x"}
    assert grid["WL1"]["sensor_findings"] == [] and grid["WT"]["open_alarm_id"] is None
    alarms = client.get("/api/v1/alarms", headers=viewer).json()["items"]
    assert "WT" not in {a["position"] for a in alarms}

    sign_in(client, keys["viewer"])
    page = client.get(f"/actuators/{wt}").text
    assert "LVDT (rod position)" in page and "<code>WT.x</code>" in page
    assert "noise floor (rms)" in page and "µm" in page
    fleet = client.get("/fleet").text
    assert "sensor finding on WT.x" in fleet


def test_a_flight_far_outside_the_design_conditions_is_named_not_alarmed(
        app, client: TestClient, keys: dict[str, str], aircraft: str, settings: Settings,
        active_model: None) -> None:  # type: ignore[no-untyped-def]
    """70 K above the day's ambient (the station accepts 30): the air temperature lies beyond
    every position's design range (its cruise mean about 48 degC, the design's up to 17), so
    every feature is set aside and none alarms."""
    viewer = auth(keys["viewer"])
    cells = {c["position"]: c for c in client.get("/api/v1/fleet/health", headers=viewer).json()}
    _analyse(client, keys, settings, _flight(aircraft, "F1", 1, ()))
    hot = _analyse(client, keys, settings,
                   _flight(aircraft, "F2", 2, (), Conditions(ambient_offset_k=70.0)))
    for p, cell in cells.items():
        [found] = client.get(f"/api/v1/actuators/{cell['actuator_id']}/sensor-findings",
                             headers=viewer).json()
        assert found["flight_id"] == hot and found["findings"] == []
        outside = {o["condition"]: o for o in found["outside_design"]}
        assert outside and all(o["value"] > o["high"] for o in outside.values())
        assert set(found["set_aside"]) == {n for o in outside.values() for n in o["features"]}
        assert {n.split(".")[0] for n in found["set_aside"]} == {p}
    assert client.get("/api/v1/alarms", headers=viewer).json()["items"] == []
    grid = {c["position"]: c for c in client.get("/api/v1/fleet/health", headers=viewer).json()}
    assert all(c["outside_design"] and not c["sensor_findings"] for c in grid.values())
    sign_in(client, keys["viewer"])
    page = client.get(f"/actuators/{cells['WT']['actuator_id']}").text
    assert "mean air temperature: outside the design" in page and "(design)" in page
    assert "latest flight outside the design (" in client.get("/fleet").text
    assert "mean air temperature" in client.get("/fleet").text
    _analyse(client, keys, settings, _flight(aircraft, "F3", 3, ()))
    grid = {c["position"]: c for c in client.get("/api/v1/fleet/health", headers=viewer).json()}
    assert all(c["outside_design"] == [] for c in grid.values())  # the latest flight's only
