"""Issue 45: an operator's sensor injection, flown in the loop by the real runner against the
real app and analysed by the real worker with the shipped model, gives a sensor finding on
that channel and no actuator alarm; the flight does not reveal it, its ground truth does."""

from __future__ import annotations

import numpy as np
from fastapi.testclient import TestClient

from server.config import Settings
from server.jobs.worker import Worker
from sim_worker.faults import healthy
from sim_worker.flight import simulate_flight
from sim_worker.sensors import SensorInjection, degrade
from sim_worker.service import Api, SimFleetRunner
from tests.api.conftest import active_model, app, auth, client, keys  # noqa: F401  (fixtures)


def _runner(client: TestClient, keys: dict[str, str]) -> SimFleetRunner:  # noqa: F811
    api = Api("http://testserver", keys["admin"], operator_key=keys["operator"],
              sleep=lambda s: None)
    api.client = client
    return SimFleetRunner(api, n_aircraft=1, rate_per_min=1e6, seed=4, duration_s=60,
                          sleep=lambda s: None)


def _analyse_all(settings: Settings) -> None:
    worker = Worker(settings)
    try:
        while worker.run_once():
            pass
    finally:
        worker.engine.dispose()


def test_an_operators_noisy_lvdt_is_flown_and_found_without_an_alarm(
        client: TestClient, keys: dict[str, str], settings: Settings,  # noqa: F811
        active_model: None) -> None:  # noqa: F811
    runner = _runner(client, keys)
    runner.register_fleet()
    run = runner.runs[0]
    tail, viewer, op = run.aircraft.tail, auth(keys["viewer"]), auth(keys["operator"])
    r = client.post("/api/v1/test-station/sensor-injections", headers=op, json={
        "aircraft": tail, "position": "WT", "sensor": "lvdt", "kind": "noise", "value": 3,
        "onset_flight": 2})
    assert r.status_code == 201, r.text
    inj = r.json()
    assert (inj["status"], inj["channels"], inj["created_by"]) == (
        "pending", ["WT.x"], "test-operator")

    for _ in range(4):  # flight 1 as rigged, 2-4 with the noisy LVDT
        assert runner.fly(run) == "accepted"
        _analyse_all(settings)

    inj = client.get(f"/api/v1/test-station/sensor-injections/{inj['id']}",
                     headers=viewer).json()
    assert (inj["status"], inj["started_flight"]) == ("active", 2)
    truth = client.get(f"/api/v1/test-station/sensor-injections/{inj['id']}/ground-truth",
                       headers=viewer).json()
    assert [(t["flight"], t["applied"]) for t in truth] == [
        (f"{tail}-F{n:05d}", 3.0) for n in (2, 3, 4)]

    cells = {c["position"]: c for c in client.get("/api/v1/fleet/health", headers=viewer
                                                  ).json()}
    found = client.get(f"/api/v1/actuators/{cells['WT']['actuator_id']}/sensor-findings",
                       headers=viewer).json()
    flights = {f["id"]: f for f in client.get(f"/api/v1/flights?aircraft={tail}",
                                              headers=viewer).json()["items"]}
    noisy = {flights[f["flight_id"]]["flight"] for f in found}
    assert noisy and noisy <= {f"{tail}-F{n:05d}" for n in (2, 3, 4)}, noisy
    assert {(g["channel"], g["sensor"]) for f in found for g in f["findings"]} == {
        ("WT.x", "lvdt")}
    for p in ("WL1", "WL2"):
        assert client.get(f"/api/v1/actuators/{cells[p]['actuator_id']}/sensor-findings",
                          headers=viewer).json() == []
    assert client.get(f"/api/v1/alarms?aircraft={tail}", headers=viewer).json()["total"] == 0
    # the flight's metadata does not reveal the injection
    doc = client.get(f"/api/v1/flights/{next(iter(flights))}", headers=viewer).text
    assert "noise" not in doc and "sensor" not in doc.replace("sensor-findings", "")

    r = client.post(f"/api/v1/test-station/sensor-injections/{inj['id']}/cancel", headers=op)
    assert r.status_code == 200 and r.json()["status"] == "cancelled"
    assert runner.fly(run) == "accepted"  # flight 5 flies as rigged: no truth reported
    assert len(client.get(f"/api/v1/test-station/sensor-injections/{inj['id']}/ground-truth",
                          headers=viewer).json()) == 3


def _flown(aircraft, injections, flight: int) -> dict[str, np.ndarray]:  # type: ignore[no-untyped-def]
    log, _ = simulate_flight(degrade(aircraft, injections, flight), healthy(), flight,
                             np.random.default_rng(flight), duration_s=15.0)
    return {k: np.asarray(v, dtype=float) for k, v in log.channels.items()}


def test_drift_and_quantisation_act_on_the_reading_the_loop_closes_on() -> None:
    from sim_worker.service import fleet_plan

    aircraft = fleet_plan(1, 0)[0]
    rigged = _flown(aircraft, [], 3)
    drift = SensorInjection(1, "WT", "lvdt", "drift", 1e-4, started=2)
    assert drift.applied(3) == 2e-4  # two flights of drift on flight 3
    drifted = _flown(aircraft, [drift], 3)
    # the loop closes on the drifting LVDT: its reading keeps following the command while the
    # rod, hence the surface, sits off by the offset (0.2 mm: a few mrad of the wingtip)
    assert abs(np.mean(drifted["WT.x"] - rigged["WT.x"])) < 2e-4 / 20
    assert np.mean(drifted["surf_WT"] - rigged["surf_WT"]) < -1e-3
    step = SensorInjection(2, "WT", "lvdt", "quantisation", 1e-4, started=1)
    coarse = _flown(aircraft, [step], 3)["WT.x"]
    assert np.allclose(coarse / 1e-4, np.round(coarse / 1e-4), atol=1e-3)
    assert not np.allclose(rigged["WT.x"] / 1e-4, np.round(rigged["WT.x"] / 1e-4), atol=1e-3)


def test_a_stuck_or_clipped_current_sensor_is_what_the_current_loop_reads() -> None:
    from sim_worker.service import fleet_plan

    aircraft = fleet_plan(1, 0)[0]
    rigged = _flown(aircraft, [], 3)
    clipped = _flown(aircraft, [SensorInjection(1, "WT", "current", "clipped", 1.0, 1)], 3)
    assert max(abs(rigged["WT.ia"]).max(), abs(rigged["WT.ib"]).max()) > 2.0
    for ch in ("WT.ia", "WT.ib", "WT.ic"):
        assert abs(clipped[ch]).max() <= 1.0
    stuck = _flown(aircraft, [SensorInjection(2, "WT", "current", "stuck", 0.0, 1)], 3)
    assert all((stuck[ch] == 0).all() for ch in ("WT.ia", "WT.ib", "WT.ic"))
    # the loop closed on the degraded reading: the wingtip flew otherwise, the winglet not
    for flown in (clipped, stuck):
        assert np.abs(flown["surf_WT"] - rigged["surf_WT"]).max() > 1e-3
        assert np.array_equal(flown["WL1.ia"], rigged["WL1.ia"])


def test_a_stuck_resolver_freezes_the_commutation_within_the_stroke() -> None:
    """Flown (the API offers it): the drive commutates on a frozen angle, so its current
    grows while the rod wanders off its command, but stays within its +-30 mm stroke (a stuck
    LVDT, refused, would run it metres away: docs/SIMULATOR.md)."""
    from sim_worker.service import fleet_plan

    aircraft = fleet_plan(1, 0)[0]
    rigged = _flown(aircraft, [], 3)
    stuck = _flown(aircraft, [SensorInjection(1, "WT", "resolver", "stuck", 0.5, 1)], 3)
    assert np.all(stuck["WT.theta"] == np.float32(0.5))
    assert np.ptp(rigged["WT.theta"]) > 1.0
    rms = {k: float(np.sqrt(np.mean(v["WT.ia"] ** 2))) for k, v in (("rigged", rigged),
                                                                  ("stuck", stuck))}
    assert rms["stuck"] > 3 * rms["rigged"], rms
    assert np.abs(stuck["WT.x"] - stuck["WT.x_cmd"]).max() > 5e-3
    assert np.abs(stuck["WT.x"]).max() < 0.030
    assert np.array_equal(stuck["WL1.ia"], rigged["WL1.ia"])


def test_the_api_steps_are_the_simulators() -> None:
    from server.schemas import NATIVE_STEP
    from sim_worker.params import SensorParams
    from sim_worker.sensors import _FIELDS

    sen = SensorParams()
    assert {s: getattr(sen, f[1]) for s, f in _FIELDS.items()} == NATIVE_STEP
