"""What the alarm records and read-outs claim after the facts change: a failed unit has no life
left, a closed alarm claims no live urgency, an alarm keeps the class it was raised with (later
changes are its events), a no-fault-found leaves no prognosis standing.

Alarm rows are written as the analysis writes them (``server/services/analysis.py``), the
failure as the test station reports it (``server/services/station_faults.py``)."""

from __future__ import annotations

from types import SimpleNamespace

from fastapi.testclient import TestClient
from sqlalchemy import select

from server.db import session_scope
from server.models import Actuator, Alarm, Flight, HealthRecord, Injection, Prognosis
from server.phm.prognosis import RulDistribution
from server.schemas import InjectionCreate
from server.services import analysis, station, station_faults
from server.services import health as health_service
from server.services.urgency import ACT_WITHIN, urgency
from tests.api.conftest import auth
from tests.web.seed import add_alarm, rul_document


def _outcome(mode: str | None, *, new: bool, index: int, confirmed: str | None = None,
             second: str | None = None, second_own: float = 0.9) -> SimpleNamespace:
    """The parts of a chain outcome ``_store_alarm`` reads (``second``: another mode present,
    with RULs for both: the unit's the earlier; ``second_own`` its own probability)."""
    modes = [m for m in (mode, second) if m]
    ruls = ({m: RulDistribution.from_dict(rul_document(index, median, 0.5, 0.1, [0.0, 100.0],
                                                       [1.0]))
             for m, median in ((mode, 40.0), (second, 25.0))} if mode and second else {})
    return SimpleNamespace(new_alarm=new, alarm=True, fault_mode=mode, flight_index=index,
                           class_probabilities={mode: 0.8} if mode else None,
                           max_confidence=0.99, alarm_features=["WT.F_MTEL"],
                           isolation={"WT": 1.0} if new else {}, confirmed=confirmed,
                           modes=modes,
                           mode_probabilities={m: second_own if m == second else 0.9
                                               for m in modes},
                           ruls=ruls, confirmed_others=[second] if second and confirmed else [],
                           confirmed_modes=[second] if second and confirmed else [])


def _alarm_item(client: TestClient, keys: dict[str, str], alarm_id: int) -> dict:
    items = client.get("/api/v1/alarms", headers=auth(keys["viewer"])).json()["items"]
    return next(a for a in items if a["id"] == alarm_id)


def test_a_failed_unit_reports_no_remaining_life(app, client, keys, aircraft) -> None:  # type: ignore[no-untyped-def]
    """Issue 7: failed at flight 71, the inbox still said RUL 11 (its last prediction)."""
    factory = app.state.session_factory
    alarm_id = add_alarm(factory, tail=aircraft, position="WT", fault_mode="DMD", rul=11.0)
    with session_scope(factory) as s:
        s.get(Alarm, alarm_id).rul_low_flights = 9.0
    assert _alarm_item(client, keys, alarm_id)["rul_median_flights"] == 11.0
    with session_scope(factory) as s:
        inj = station.create(session=s, kind=station.FAULTS, created_by="test",
                             spec=InjectionCreate(aircraft=aircraft, position="WT",
                                                  fault_mode="DMD", onset_flight=0,
                                                  time_to_failure_flights=60))
        station_faults.set_status(session=s, row=s.get(Injection, inj.id),
                                                status="failed", failure_flight=71)

    item = _alarm_item(client, keys, alarm_id)
    assert (item["urgency"], item["rul_median_flights"], item["rul_low_flights"]) == (
        "replace_now", 0.0, 0.0)
    cells = client.get("/api/v1/fleet/health", headers=auth(keys["viewer"])).json()
    cell = next(c for c in cells if c["tail"] == aircraft and c["position"] == "WT")
    assert (cell["failed_at_flight"], cell["rul_median"], cell["rul_low"]) == (71, 0.0, 0.0)


def test_an_alarm_lists_every_mode_present_and_follows_them(  # type: ignore[no-untyped-def]
        app, client, keys, aircraft) -> None:
    """Two modes on one unit: the alarm lists both with their own probability and median RUL,
    the leading one first, provisional until confirmed (each confirmation its own event); a
    flight naming one mode again lists that one."""
    factory = app.state.session_factory
    first = add_alarm(factory, tail=aircraft, position="WT", fault_mode="TTS")
    with session_scope(factory) as s:
        act_id = s.get(Alarm, first).actuator_id
        s.delete(s.get(Alarm, first))
    with session_scope(factory) as s:
        flight = s.scalar(select(Flight).where(Flight.tail == aircraft))
        act = s.get(Actuator, act_id)
        analysis._store_alarm(s, flight, act, _outcome("TTS", new=True, index=30,
                                                       second="DMD", second_own=0.2), None)
        alarm_id = s.scalar(select(Alarm.id).where(Alarm.actuator_id == act_id))
    # DMD named below the threshold: by its own feature, beyond TTS's cross-talk
    assert _alarm_item(client, keys, alarm_id)["modes"] == [
        {"mode": "TTS", "probability": 0.9, "rul_median_flights": 40.0, "confirmed": False,
         "by_feature": False},
        {"mode": "DMD", "probability": 0.2, "rul_median_flights": 25.0, "confirmed": False,
         "by_feature": True}]
    with session_scope(factory) as s:  # both confirmed on one flight: two events
        analysis._store_alarm(s, flight, s.get(Actuator, act_id),
                              _outcome("TTS", new=False, index=31, second="DMD",
                                       confirmed="TTS"), None)
    assert [m["confirmed"] for m in _alarm_item(client, keys, alarm_id)["modes"]] == [
        True, True]
    events = client.get(f"/api/v1/alarms/{alarm_id}/events", headers=auth(keys["viewer"]))
    assert sorted((e["kind"], e["to_mode"], e["flight_index"]) for e in events.json()) == [
        ("confirmed", "DMD", 31), ("confirmed", "TTS", 31)]
    with session_scope(factory) as s:
        analysis._store_alarm(s, flight, s.get(Actuator, act_id),
                              _outcome("TTS", new=False, index=32), None)
    assert _alarm_item(client, keys, alarm_id)["modes"] == [
        {"mode": "TTS", "probability": 0.9, "rul_median_flights": None, "confirmed": True,
         "by_feature": False}]


def test_a_closed_alarm_claims_no_live_urgency(app, client, keys, aircraft) -> None:  # type: ignore[no-untyped-def]
    """Issue 9: a closed alarm still said ``urgency: replace_now`` in the API."""
    alarm_id = add_alarm(app.state.session_factory, tail=aircraft, position="WT",
                         fault_mode="BDO", rul=None)
    assert _alarm_item(client, keys, alarm_id)["urgency"] == "replace_now"
    r = client.post(f"/api/v1/alarms/{alarm_id}/close", headers=auth(keys["admin"]),
                    json={"note": "spurious"})
    assert r.status_code == 200, r.text
    for item in (r.json(), _alarm_item(client, keys, alarm_id)):
        assert item["status"] == "closed"
        assert (item["urgency"], item["urgency_label"], item["act_within_flights"]) == (
            None, None, None)


def test_an_alarm_keeps_its_class_at_raising_and_records_changes_as_events(  # type: ignore[no-untyped-def]
        app, client, keys, aircraft) -> None:
    """Issue 10: raised as MTEL, shown later as DMD; the no-fault-found record named DMD."""
    factory = app.state.session_factory
    first = add_alarm(factory, tail=aircraft, position="WT", fault_mode="MTEL")
    with session_scope(factory) as s:  # start over from the analysis' own writes
        act_id = s.get(Alarm, first).actuator_id
        s.delete(s.get(Alarm, first))
    with session_scope(factory) as s:
        flight = s.scalar(select(Flight).where(Flight.tail == aircraft))
        act = s.get(Actuator, act_id)
        analysis._store_alarm(s, flight, act, _outcome("MTEL", new=True, index=30), None)
        analysis._store_alarm(s, flight, act, _outcome("MTEL", new=False, index=31), None)
        analysis._store_alarm(s, flight, act, _outcome("DMD", new=False, index=32), None)
        alarm_id = s.scalar(select(Alarm.id).where(Alarm.actuator_id == act_id))
    item = _alarm_item(client, keys, alarm_id)
    assert item["confirmed_fault_mode"] is None  # provisional
    with session_scope(factory) as s:
        analysis._store_alarm(s, flight, act, _outcome("DMD", new=False, index=33,
                                                       confirmed="DMD"), None)

    item = _alarm_item(client, keys, alarm_id)
    assert (item["raised_fault_mode"], item["fault_mode"]) == ("MTEL", "DMD")
    assert (item["confirmed_fault_mode"], item["isolation"]) == ("DMD", {"WT": 1.0})
    events = client.get(f"/api/v1/alarms/{alarm_id}/events", headers=auth(keys["viewer"]))
    assert events.status_code == 200, events.text
    assert [(e["kind"], e["from_mode"], e["to_mode"], e["flight_index"])
            for e in events.json()] == [("class_change", "MTEL", "DMD", 32),
                                        ("confirmed", None, "DMD", 33)]
    assert client.get("/api/v1/alarms/99999/events",
                      headers=auth(keys["viewer"])).status_code == 404

    r = client.post(f"/api/v1/actuators/{act_id}/inspect", headers=auth(keys["maintainer"]),
                    json={"work_order": "WO-NFF-1"})
    assert r.status_code == 201, r.text
    item = _alarm_item(client, keys, alarm_id)
    assert (item["resolution"], item["raised_fault_mode"], item["urgency"]) == (
        "no_fault_found", "MTEL", None)


def test_no_prognosis_stands_after_a_no_fault_found(app, client, keys, aircraft) -> None:  # type: ignore[no-untyped-def]
    """Issue 9: after no fault found the page still read DMD, "RUL at least 164" and a cone
    from the prognoses of the closed alarm; a new alarm starts its own."""
    factory = app.state.session_factory

    def analysed_alarm(index: int) -> int:
        """An alarm on WT raised on its flight ``index``, with that flight's prognosis."""
        alarm_id = add_alarm(factory, tail=aircraft, position="WT", fault_mode="DMD")
        with session_scope(factory) as s:
            alarm = s.get(Alarm, alarm_id)
            s.add(HealthRecord(actuator_id=alarm.actuator_id, flight_id=alarm.flight_id,
                               flight_index=index, confidence=0.99, alarm=True))
            s.add(Prognosis(actuator_id=alarm.actuator_id, flight_id=alarm.flight_id,
                            flight_index=index, fault_mode="DMD", distribution=rul_document(
                                index, 200.0, 0.3, 0.05, [0.0, 400.0], [1.0])))
            return alarm.actuator_id

    def current() -> list[int]:
        with session_scope(factory) as s:
            return [p.flight_index for p in health_service.current_prognoses(
                session=s, actuator_id=act_id, limit=100)]

    act_id = analysed_alarm(1)
    assert current() == [1]
    r = client.post(f"/api/v1/actuators/{act_id}/inspect", headers=auth(keys["maintainer"]),
                    json={"work_order": "WO-NFF-2"})
    assert r.status_code == 201, r.text
    assert current() == []
    # the history is still there for whoever asks for it
    hist = client.get(f"/api/v1/actuators/{act_id}/prognoses", headers=auth(keys["viewer"]))
    assert [p["flight_index"] for p in hist.json()] == [1]
    analysed_alarm(5)  # a new alarm: its own prognoses, not the closed one's
    assert current() == [5]


def test_act_within_says_one_flight_in_the_singular() -> None:
    """Issue 12: "act within 1 flights"."""
    one = urgency(failed_at_flight=None, alarm_open=True, fault_mode="DMD", rul_low_flights=1.4)
    assert (one.bucket, one.label) == (ACT_WITHIN, "act within 1 flight")
    assert one.reason.endswith("quantile 1 flight")
    two = urgency(failed_at_flight=None, alarm_open=True, fault_mode="DMD", rul_low_flights=2.0)
    assert two.label == "act within 2 flights"
