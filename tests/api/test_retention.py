"""Raw-log retention (``server/services/retention.py``): the bytes of old healthy flights go,
their results stay; flights in alarm keep theirs; a pruned flight's signals answer 410."""

from __future__ import annotations

from datetime import datetime, timedelta, timezone

from fastapi.testclient import TestClient
from sqlalchemy import select

from server.db import session_scope
from server.models import Actuator, Flight, HealthRecord
from server.services.retention import prune_healthy_raw
from tests.api.conftest import auth
from tests.flightlog_factory import make_parquet

PARQUET = {"Content-Type": "application/vnd.apache.parquet"}


def _analysed(app, flight_id: int, index: int, alarm: bool) -> None:  # type: ignore[no-untyped-def]
    """The flight as the analysis leaves it: analysed, one health record per actuator."""
    with session_scope(app.state.session_factory) as s:
        flight = s.get(Flight, flight_id)
        flight.status = "analyzed"
        flight.started_at = datetime(2026, 1, 1, tzinfo=timezone.utc) + timedelta(hours=index)
        for act in s.scalars(select(Actuator).where(Actuator.aircraft_id == flight.aircraft_id)):
            s.add(HealthRecord(actuator_id=act.id, flight_id=flight_id, flight_index=index,
                               features={}, scores={}, confidence=0.1,
                               alarm=alarm and act.position == "WT"))


def test_old_healthy_raw_logs_are_pruned_results_and_alarm_flights_kept(
        app, client: TestClient, keys: dict[str, str], aircraft: str) -> None:  # type: ignore[no-untyped-def]
    ids = []
    for i in range(6):
        r = client.post("/api/v1/flights", content=make_parquet(aircraft, f"F{i:04d}", seed=i),
                        headers={**PARQUET, **auth(keys["uploader"])})
        assert r.status_code == 202, r.text
        ids.append(r.json()["id"])
        _analysed(app, ids[-1], i, alarm=(i == 1))
    with session_scope(app.state.session_factory) as s:
        paths = {f.id: app.state.blobs.root / f.blob_path for f in s.scalars(select(Flight))}
    assert all(p.exists() for p in paths.values())

    with app.state.session_factory() as s:
        pruned = prune_healthy_raw(session=s, blobs=app.state.blobs,
                                   aircraft_id=_aircraft_id(app, ids[0]), keep=2)
    # healthy flights 0, 2, 3 go (flights 4 and 5 are the two most recent healthy ones);
    # flight 1 had an actuator in alarm and keeps its log
    assert pruned == 3
    gone = {ids[0], ids[2], ids[3]}
    for fid, path in paths.items():
        assert path.exists() == (fid not in gone), fid
    viewer = auth(keys["viewer"])
    r = client.get(f"/api/v1/flights/{ids[0]}/signals", headers=viewer)
    assert r.status_code == 410 and r.json()["error"]["code"] == "raw_pruned"
    assert client.get(f"/api/v1/flights/{ids[1]}/signals", headers=viewer).status_code == 200
    assert client.get(f"/api/v1/flights/{ids[0]}", headers=viewer).status_code == 200
    with session_scope(app.state.session_factory) as s:  # the results stay
        assert s.scalar(select(HealthRecord).where(HealthRecord.flight_id == ids[0]))
    with app.state.session_factory() as s:  # nothing more to prune
        assert prune_healthy_raw(session=s, blobs=app.state.blobs,
                                 aircraft_id=_aircraft_id(app, ids[0]), keep=2) == 0


def _aircraft_id(app, flight_id: int) -> int:  # type: ignore[no-untyped-def]
    with session_scope(app.state.session_factory) as s:
        return int(s.get(Flight, flight_id).aircraft_id)
