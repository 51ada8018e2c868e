"""The sim worker flying concurrent test-station injections against the real app (FastAPI's test
client is an ``httpx.Client``): every live injection's fault on board, each advanced and
reported on its own; a failure ends that injection, the replacement every fault on its unit,
and a fault on another actuator flies on."""

from __future__ import annotations

from typing import Any

from fastapi.testclient import TestClient

from tests.api.conftest import app, auth, client, keys  # noqa: F401  (fixtures)
from tests.sim.test_service_failure import _runner


def _truth(client: TestClient, viewer: dict[str, str], inj: int  # noqa: F811
           ) -> list[dict[str, Any]]:
    return client.get(f"/api/v1/test-station/injections/{inj}/ground-truth",
                      headers=viewer).json()


def _injection(client: TestClient, viewer: dict[str, str], inj: int  # noqa: F811
               ) -> dict[str, Any]:
    return client.get(f"/api/v1/test-station/injections/{inj}", headers=viewer).json()


def test_two_faults_on_one_actuator_and_one_on_another_fly_together(  # noqa: F811
        client: TestClient, keys: dict[str, str]) -> None:  # noqa: F811
    runner = _runner(client, keys)
    runner.register_fleet()
    run = runner.runs[0]
    tail, op, viewer = run.aircraft.tail, auth(keys["operator"]), auth(keys["viewer"])
    ids = {}
    for position, mode, onset, ttf in (("WT", "TTS", 1, 10), ("WT", "DMD", 3, 60),
                                       ("WL1", "MTWEAR", 2, 40)):
        r = client.post("/api/v1/test-station/injections", headers=op, json={
            "aircraft": tail, "position": position, "fault_mode": mode, "onset_flight": onset,
            "time_to_failure_flights": ttf})
        assert r.status_code == 201, r.text
        ids[(position, mode)] = r.json()["id"]
    on_board: dict[int, set[tuple[str, str]]] = {}
    outcomes = []
    while "grounded" not in outcomes and len(outcomes) < 40:
        n = run.next_flight
        outcomes.append(runner.fly(run))
        on_board[n] = {(f.position, f.mode) for f in run.faults}
    assert outcomes[-1] == "grounded" and set(outcomes[:-1]) == {"accepted"}, outcomes
    assert on_board[1] == {("WT", "TTS")} and on_board[2] == {("WT", "TTS"), ("WL1", "MTWEAR")}
    assert on_board[3] == {("WT", "TTS"), ("WT", "DMD"), ("WL1", "MTWEAR")}

    tts = _injection(client, viewer, ids[("WT", "TTS")])
    failure = tts["failure_flight"]
    assert tts["status"] == "failed" and abs(failure - 11) <= 1, tts
    for (_, mode), inj in ids.items():  # each reported from its own onset
        truth = _truth(client, viewer, inj)
        onset = {"TTS": 1, "DMD": 3, "MTWEAR": 2}[mode]
        assert [t["flight_number"] for t in truth] == list(range(onset, failure)), mode
        severities = [t["severity_norm"] for t in truth]
        assert abs(severities[0] - 0.05) < 1e-12 and severities == sorted(severities), mode
        if mode == "TTS":
            assert [t["true_rul_flights"] for t in truth] == [failure - t["flight_number"]
                                                              for t in truth]
        else:
            assert {t["true_rul_flights"] for t in truth} == {None}
            assert _injection(client, viewer, inj)["status"] == "active"

    unit = client.get(f"/api/v1/aircraft/{tail}", headers=viewer).json()["actuators"]["WT"]
    r = client.post(f"/api/v1/actuators/{unit['id']}/replace", headers=auth(keys["maintainer"]),
                    json={"new_serial": "WT-SPARE-2", "work_order": "WO-2026-0101"})
    assert r.status_code == 201, r.text
    # the second fault on the failed unit ends with it (censored); the winglet's flies on
    dmd = _injection(client, viewer, ids[("WT", "DMD")])
    assert dmd["status"] == "cancelled" and dmd["failure_flight"] is None
    assert runner.fly(run) == "accepted"
    assert [(f.position, f.mode) for f in run.faults] == [("WL1", "MTWEAR")]
    mtwear = _truth(client, viewer, ids[("WL1", "MTWEAR")])
    assert mtwear[-1]["flight_number"] == failure
    assert mtwear[-1]["severity_norm"] > mtwear[-2]["severity_norm"]
    assert len(_truth(client, viewer, ids[("WT", "DMD")])) == failure - 3
