"""The runner's requests per flight against the real app (FastAPI's test client is an
``httpx.Client``): the flight's plan, its truth and its upload, whatever the test station has
on the aircraft; the flight its fault fails on too (its truth then back-fills the true RUL)."""

from __future__ import annotations

from fastapi.testclient import TestClient

from tests.api.conftest import app, auth, client, keys  # noqa: F401  (fixtures)
from tests.sim.test_service_failure import _runner

PLAN, UPLOAD = "GET /api/v1/test-station/plan", "POST /api/v1/flights"


def test_three_requests_a_flight_with_a_fault_a_sensor_and_a_condition_on(  # noqa: F811
        client: TestClient, keys: dict[str, str]) -> None:  # noqa: F811
    runner = _runner(client, keys)
    runner.register_fleet()
    run = runner.runs[0]
    tail, op = run.aircraft.tail, auth(keys["operator"])
    for kind, body in (("injections", {"position": "WT", "fault_mode": "TTS",
                                       "time_to_failure_flights": 10}),
                       ("sensor-injections", {"position": "WL1", "sensor": "lvdt",
                                              "kind": "noise", "value": 3}),
                       ("conditions", {"kind": "load_scale", "value": 1.2})):
        r = client.post(f"/api/v1/test-station/{kind}", headers=op,
                        json={"aircraft": tail, "onset_flight": 2, **body})
        assert r.status_code == 201, r.text
    sent: list[str] = []
    client.event_hooks["request"].append(lambda r: sent.append(f"{r.method} {r.url.path}"))
    flights: dict[int, tuple[str, list[str]]] = {}
    while not flights or flights[max(flights)][0] != "grounded":
        n, before = run.next_flight, len(sent)
        flights[len(flights) + 1] = (runner.fly(run), sent[before:])
        assert n <= 40, flights
    outcome, requests = flights.pop(1)  # nothing on flight 1: no truth to report
    assert (outcome, requests) == ("accepted", [PLAN, UPLOAD])
    grounded = flights.pop(max(flights))
    assert grounded == ("grounded", [PLAN])
    assert len(flights) >= 9, flights  # flown 2 .. failure, steered to flight 2 + 10
    for n, (outcome, requests) in flights.items():
        assert (outcome, [r.split("?")[0] for r in requests]) == (
            "accepted", [PLAN, f"PUT /api/v1/test-station/flights/{tail}-F{n:05d}", UPLOAD])

    viewer = auth(keys["viewer"])
    fault = client.get(f"/api/v1/test-station/injections?aircraft={tail}", headers=viewer
                       ).json()["items"][0]
    assert fault["status"] == "failed" and fault["failure_flight"] == max(flights) + 1
    truth = client.get(f"/api/v1/test-station/injections/{fault['id']}/ground-truth",
                       headers=viewer).json()
    assert [(t["flight_number"], t["true_rul_flights"]) for t in truth] == [
        (n, fault["failure_flight"] - n) for n in flights]
