"""The sim worker's failed-drive rule (``sim_worker/service.py``): a drive at failure grounds
its aircraft and is never healed until the unit is replaced on the service, restarts included.
The runner talks to the real app (FastAPI's test client is an ``httpx.Client``)."""

from __future__ import annotations

from fastapi.testclient import TestClient

from sim_worker.service import Api, SimFleetRunner
from tests.api.conftest import app, auth, client, keys  # noqa: F401  (fixtures)


def _runner(client: TestClient, keys: dict[str, str]) -> SimFleetRunner:  # noqa: F811
    api = Api("http://testserver", keys["admin"], operator_key=keys["operator"],
              sleep=lambda s: None)
    api.client = client
    return SimFleetRunner(api, n_aircraft=1, rate_per_min=1e6, seed=3, duration_s=15,
                          sleep=lambda s: None)


def _flights(client: TestClient, keys: dict[str, str]) -> int:  # noqa: F811
    return client.get("/api/v1/flights?limit=1", headers=auth(keys["viewer"])).json()["total"]


def test_a_failed_drive_grounds_the_aircraft_and_never_heals(client: TestClient,  # noqa: F811
                                                             keys: dict[str, str]) -> None:  # noqa: F811
    runner = _runner(client, keys)
    runner.register_fleet()
    run = runner.runs[0]
    tail = run.aircraft.tail
    op = auth(keys["operator"])
    inj = client.post("/api/v1/test-station/injections", headers=op, json={
        "aircraft": tail, "position": "WT", "fault_mode": "TTS", "onset_flight": 1,
        "time_to_failure_flights": 10}).json()
    outcomes = []
    while "grounded" not in outcomes and len(outcomes) < 60:
        outcomes.append(runner.fly(run))
    assert outcomes[-1] == "grounded" and set(outcomes[:-1]) == {"accepted"}, outcomes
    viewer = auth(keys["viewer"])
    injection = client.get(f"/api/v1/test-station/injections/{inj['id']}", headers=viewer
                           ).json()
    assert injection["status"] == "failed"
    failure_flight = injection["failure_flight"]
    # steered to the operator's time to failure, counted from the flight it started on
    assert injection["planned_failure_flight"] == 1 + 10
    assert abs(failure_flight - injection["planned_failure_flight"]) <= 1, injection
    unit = client.get(f"/api/v1/aircraft/{tail}", headers=viewer).json()["actuators"]["WT"]
    assert unit["failed_at_flight"] == failure_flight
    cell = next(c for c in client.get("/api/v1/fleet/health", headers=viewer).json()
                if c["position"] == "WT")
    assert (cell["status"], cell["failed_at_flight"]) == ("red", failure_flight)

    faults, flown = run.faults, _flights(client, keys)
    for _ in range(5):  # grounded: nothing flown, the fault kept at failure
        assert runner.fly(run) == "grounded"
    assert run.faults == faults and [f.mode for f in faults] == ["TTS"] and faults[0].failed
    assert _flights(client, keys) == flown

    restarted = _runner(client, keys)  # a restart does not heal it either
    restarted.register_fleet()
    assert restarted.fly(restarted.runs[0]) == "grounded"
    assert restarted.run(max_flights=3) == 0 and _flights(client, keys) == flown

    r = client.post(f"/api/v1/actuators/{unit['id']}/replace", headers=auth(keys["maintainer"]),
                    json={"new_serial": "WT-SPARE-1", "work_order": "WO-2026-0100"})
    assert r.status_code == 201, r.text
    assert restarted.fly(restarted.runs[0]) == "accepted"
    assert restarted.runs[0].faults == ()
    assert restarted.runs[0].aircraft.serials["WT"] == "WT-SPARE-1"
    assert runner.fly(run) in ("accepted", "duplicate") and run.faults == ()
