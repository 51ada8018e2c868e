"""Issue 45: an operator's simulation conditions (+15 K air, 1.5x hinge load), flown by the
real runner against the real app and analysed by the real worker with the shipped model: the
air the flights record is 15 K warmer, no actuator alarm, the flights do not name the
conditions, their ground truth does, and a cancel ends them (SQLite and PostgreSQL)."""

from __future__ import annotations

import numpy as np
from fastapi.testclient import TestClient

from server.config import Settings
from sim_worker.faults import healthy
from sim_worker.flight import flight_start, simulate_flight
from tests.api.conftest import active_model, app, auth, client, keys  # noqa: F401  (fixtures)
from tests.sim.test_sensor_injections import _analyse_all, _runner

URL = "/api/v1/test-station/conditions"


def _t_amb(client: TestClient, viewer: dict[str, str], flight_id: int  # noqa: F811
           ) -> tuple[np.ndarray, int]:
    doc = client.get(f"/api/v1/flights/{flight_id}/signals?channels=T_amb&max_points=200",
                     headers=viewer).json()
    return np.asarray(doc["channels"]["T_amb"]), int(doc["decimation"])


def test_an_operators_hot_heavy_flights_are_flown_recorded_and_raise_no_alarm(
        client: TestClient, keys: dict[str, str], settings: Settings,  # noqa: F811
        active_model: None) -> None:  # noqa: F811
    runner = _runner(client, keys)
    runner.register_fleet()
    run = runner.runs[0]
    tail, viewer, op = run.aircraft.tail, auth(keys["viewer"]), auth(keys["operator"])
    made = [client.post(URL, headers=op, json={"aircraft": tail, "kind": kind, "value": value,
                                                "onset_flight": 2})
            for kind, value in (("ambient_offset", 15), ("load_scale", 1.5))]
    assert [r.status_code for r in made] == [201, 201], [r.text for r in made]

    for _ in range(4):  # flight 1 as drawn, 2-4 hot and heavy
        assert runner.fly(run) == "accepted"
        _analyse_all(settings)

    for r in made:
        c = r.json()
        doc = client.get(f"{URL}/{c['id']}", headers=viewer).json()
        assert (doc["status"], doc["started_flight"]) == ("active", 2)
        truth = client.get(f"{URL}/{c['id']}/ground-truth", headers=viewer).json()
        assert [(t["flight"], t["applied"]) for t in truth] == [
            (f"{tail}-F{n:05d}", c["value"]) for n in (2, 3, 4)]

    flights = {f["flight"]: f for f in client.get(f"/api/v1/flights?aircraft={tail}",
                                                  headers=viewer).json()["items"]}
    assert {f["status"] for f in flights.values()} == {"analyzed"}
    # the air flight 2 recorded is 15 K warmer than the same flight drawn without the condition
    hot, step = _t_amb(client, viewer, flights[f"{tail}-F00002"]["id"])
    drawn, _ = simulate_flight(run.aircraft, healthy(), 2, np.random.default_rng(
        [runner.seed, 13, run.index, 2]), started_at=flight_start(2),
        duration_s=runner.duration_s)
    assert np.allclose(hot - np.asarray(drawn.channels["T_amb"])[::step][:hot.size], 15.0,
                       atol=0.05)
    assert client.get(f"/api/v1/alarms?aircraft={tail}", headers=viewer).json()["total"] == 0
    doc = client.get(f"/api/v1/flights/{flights[f'{tail}-F00002']['id']}", headers=viewer).text
    assert "ambient" not in doc and "load_scale" not in doc and "condition" not in doc

    for r in made:
        assert client.post(f"{URL}/{r.json()['id']}/cancel", headers=op).status_code == 200
    assert runner.fly(run) == "accepted"  # flight 5 flies as drawn: no truth reported
    assert len(client.get(f"{URL}/{made[0].json()['id']}/ground-truth", headers=viewer
                          ).json()) == 3
