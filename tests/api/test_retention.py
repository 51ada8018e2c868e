"""Raw-log retention (``server/services/retention.py``) on a real SQLite database and real blob
files: an aircraft keeps the raw logs of its last K analysed flights, healthy or in alarm, and
of the flights that raised or changed an alarm; the others' files go, their results stay; a
pruned flight's signals answer 410."""

from __future__ import annotations

from datetime import datetime, timedelta, timezone

from fastapi.testclient import TestClient
from sqlalchemy import select

from server.db import session_scope
from server.models import Actuator, Alarm, AlarmEvent, Flight, HealthRecord
from server.services.retention import prune_raw
from tests.api.conftest import auth
from tests.flightlog_factory import make_parquet

PARQUET = {"Content-Type": "application/vnd.apache.parquet"}


def _analysed(app, flight_id: int, index: int, alarm: bool) -> None:  # type: ignore[no-untyped-def]
    """The flight as the analysis leaves it: analysed, one health record per actuator, WT in
    alarm if ``alarm``."""
    with session_scope(app.state.session_factory) as s:
        flight = s.get(Flight, flight_id)
        flight.status = "analyzed"
        flight.started_at = datetime(2026, 1, 1, tzinfo=timezone.utc) + timedelta(hours=index)
        for act in s.scalars(select(Actuator).where(Actuator.aircraft_id == flight.aircraft_id)):
            s.add(HealthRecord(actuator_id=act.id, flight_id=flight_id, flight_index=index,
                               features={}, scores={}, confidence=0.1,
                               alarm=alarm and act.position == "WT"))


def _wt(app, flight_id: int) -> int:  # type: ignore[no-untyped-def]
    with session_scope(app.state.session_factory) as s:
        aircraft_id = s.get(Flight, flight_id).aircraft_id
        return int(s.scalar(select(Actuator.id).where(Actuator.aircraft_id == aircraft_id,
                                                      Actuator.position == "WT")))


def test_raw_logs_beyond_the_last_flights_go_in_alarm_too_turning_points_kept(
        app, client: TestClient, keys: dict[str, str], aircraft: str) -> None:  # type: ignore[no-untyped-def]
    """Flight 0 healthy; WT in alarm from flight 1 (raised there), its class changed on flight
    2; keep 2: flights 5 and 6 are the last two, 1 and 2 the alarm's turning points, 7 not yet
    analysed; 0, 3 and 4 lose their files -- 3 and 4 in alarm (the old rule kept every flight
    in alarm: an aircraft in alarm grew by a log a flight)."""
    ids = []
    for i in range(8):
        r = client.post("/api/v1/flights", content=make_parquet(aircraft, f"F{i:04d}", seed=i),
                        headers={**PARQUET, **auth(keys["uploader"])})
        assert r.status_code == 202, r.text
        ids.append(r.json()["id"])
        if i < 7:
            _analysed(app, ids[-1], i, alarm=i >= 1)
    wt = _wt(app, ids[0])
    with session_scope(app.state.session_factory) as s:
        alarm = Alarm(actuator_id=wt, flight_id=ids[1], status="open", confidence=0.9,
                      fault_mode="DMD")
        s.add(alarm)
        s.flush()
        s.add(AlarmEvent(alarm_id=alarm.id, flight_id=ids[2], flight_index=2,
                         kind="class_change", from_mode="DMD", to_mode="BDO"))
        paths = {f.id: app.state.blobs.root / f.blob_path for f in s.scalars(select(Flight))}
    assert all(p.exists() for p in paths.values())
    aircraft_id = _aircraft_id(app, ids[0])

    with app.state.session_factory() as s:
        pruned = prune_raw(session=s, blobs=app.state.blobs, aircraft_id=aircraft_id, keep=2)
    gone = {ids[0], ids[3], ids[4]}
    assert pruned == len(gone)
    for fid, path in paths.items():
        assert path.exists() == (fid not in gone), fid
    viewer = auth(keys["viewer"])
    r = client.get(f"/api/v1/flights/{ids[3]}/signals", headers=viewer)
    assert r.status_code == 410 and r.json()["error"]["code"] == "raw_pruned"
    assert client.get(f"/api/v1/flights/{ids[1]}/signals", headers=viewer).status_code == 200
    assert client.get(f"/api/v1/flights/{ids[3]}", headers=viewer).status_code == 200
    with session_scope(app.state.session_factory) as s:  # the results stay
        assert s.scalar(select(HealthRecord).where(HealthRecord.flight_id == ids[3]))

    # the next flight analysed: flight 5 falls out of the last two, still in alarm
    _analysed(app, ids[7], 7, alarm=True)
    with app.state.session_factory() as s:
        assert prune_raw(session=s, blobs=app.state.blobs, aircraft_id=aircraft_id,
                         keep=2) == 1
    assert not paths[ids[5]].exists() and paths[ids[6]].exists() and paths[ids[7]].exists()
    kept = [f for f in paths.values() if f.exists()]
    assert len(kept) == 2 + 2  # the bound: K plus the alarm's turning points


def test_an_alarm_keeps_the_logs_of_its_last_class_changes_only(
        app, client: TestClient, keys: dict[str, str], aircraft: str) -> None:  # type: ignore[no-untyped-def]
    """An alarm raised on flight 0 whose class changed on flights 1-6 (flickering): with keep
    1, flight 7 is the last, 0 raised the alarm, 3-6 made its last four changes; 1 and 2 go
    (one log per change would grow without bound while the class flickers)."""
    from server.services.retention import CLASS_CHANGES_KEPT

    ids = []
    for i in range(8):
        r = client.post("/api/v1/flights", content=make_parquet(aircraft, f"C{i:04d}", seed=i),
                        headers={**PARQUET, **auth(keys["uploader"])})
        assert r.status_code == 202, r.text
        ids.append(r.json()["id"])
        _analysed(app, ids[-1], i, alarm=True)
    with session_scope(app.state.session_factory) as s:
        alarm = Alarm(actuator_id=_wt(app, ids[0]), flight_id=ids[0], status="open",
                      confidence=0.9, fault_mode="DMD")
        s.add(alarm)
        s.flush()
        for i in range(1, 7):
            s.add(AlarmEvent(alarm_id=alarm.id, flight_id=ids[i], flight_index=i,
                             kind="class_change", from_mode="DMD" if i % 2 else "MTEL",
                             to_mode="MTEL" if i % 2 else "DMD"))
        paths = {f.id: app.state.blobs.root / f.blob_path for f in s.scalars(select(Flight))}
    with app.state.session_factory() as s:
        prune_raw(session=s, blobs=app.state.blobs, aircraft_id=_aircraft_id(app, ids[0]),
                  keep=1)
    assert CLASS_CHANGES_KEPT == 4
    kept = {i for i, fid in enumerate(ids) if paths[fid].exists()}
    assert kept == {0, 3, 4, 5, 6, 7}


def _aircraft_id(app, flight_id: int) -> int:  # type: ignore[no-untyped-def]
    with session_scope(app.state.session_factory) as s:
        return int(s.get(Flight, flight_id).aircraft_id)
