"""One live test-station item per slot, held by the database (migration 0013) as well as by the
services' check: a request whose check ran before a concurrent one committed still gets the
409, not a second live item, on SQLite and PostgreSQL."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import pytest
from sqlalchemy.orm import Session, sessionmaker

from server.errors import Conflict
from server.models import Injection, SensorInjection, SimCondition
from server.schemas import ConditionCreate, InjectionCreate, SensorInjectionCreate
from server.services import fleet, station

SERIALS = {"WL1": "S-1", "WL2": "S-2", "WT": "S-3"}


@pytest.fixture
def factory(factory: sessionmaker[Session]) -> sessionmaker[Session]:
    """The suite's migrated session factory, with one aircraft to schedule on."""
    with factory() as s:
        fleet.create_aircraft(session=s, tail="I-SLOT", base="Turin", serials=SERIALS)
        s.commit()
    return factory


def _injection(aircraft_id: int, **kw: Any) -> Injection:
    return Injection(aircraft_id=aircraft_id, position=kw.get("position", "WT"),
                     fault_mode="DMD", onset_flight=0, time_to_failure_flights=100,
                     created_by="t", status="pending")


def _sensor(aircraft_id: int, **kw: Any) -> SensorInjection:
    return SensorInjection(aircraft_id=aircraft_id, position="WT", sensor=kw.get("sensor", "lvdt"),
                           kind="noise", value=2.0, onset_flight=0, created_by="t",
                           status="pending")


def _condition(aircraft_id: int, **kw: Any) -> SimCondition:
    return SimCondition(aircraft_id=aircraft_id, kind=kw.get("kind", "ambient_offset"),
                        value=5.0, onset_flight=0, created_by="t", status="pending")


SPECS = {"injection": (station.FAULTS, InjectionCreate(
    aircraft="I-SLOT", position="WT", fault_mode="DMD", onset_flight=0,
    time_to_failure_flights=100)),
         "sensor": (station.SENSORS, SensorInjectionCreate(
             aircraft="I-SLOT", position="WT", sensor="lvdt", kind="noise", value=2.0,
             onset_flight=0)),
         "condition": (station.CONDITIONS, ConditionCreate(
             aircraft="I-SLOT", kind="ambient_offset", value=5.0, onset_flight=0))}


def _create(kind: str, s: Session) -> Any:
    registered, spec = SPECS[kind]
    return station.create(session=s, kind=registered, spec=spec, created_by="t")


def _add_live(s: Session, row: Any) -> None:
    """``row`` inserted as the service inserts a new item once its check has passed."""
    s.add(row)
    s.flush()


ROWS: dict[str, Callable[..., Any]] = {"injection": _injection, "sensor": _sensor,
                                       "condition": _condition}


@pytest.mark.parametrize("kind", list(ROWS))
def test_a_racing_second_live_item_is_a_409_not_a_second_row(
        kind: str, factory: sessionmaker[Session]) -> None:
    with factory() as first:
        row = _create(kind, first)
        first.commit()
        aircraft_id = row.aircraft_id
    with factory() as racing:  # its check ran before the first committed: straight to insert
        registered, spec = SPECS[kind]
        with pytest.raises(Conflict) as refused:
            station.add_live(racing, registered, ROWS[kind](aircraft_id), spec)
        assert "concurrently" in refused.value.message
        racing.rollback()
        assert racing.query(type(row)).count() == 1


@pytest.mark.parametrize("kind", list(ROWS))
def test_a_cancelled_item_frees_its_slot_and_other_slots_stay_free(
        kind: str, factory: sessionmaker[Session]) -> None:
    with factory() as s:
        row = _create(kind, s)
        s.commit()
        aircraft_id = row.aircraft_id
        if kind == "sensor":  # another sensor of the same actuator is another slot
            _add_live(s, _sensor(aircraft_id, sensor="current"))
        if kind == "condition":  # another kind of condition on the same aircraft too
            _add_live(s, _condition(aircraft_id, kind="load_scale"))
        with pytest.raises(Conflict):
            _create(kind, s)  # the service's own check: the friendly 409
        s.rollback()
        row = s.get(type(row), row.id)
        row.status = "cancelled"
        s.commit()
        _create(kind, s)
        s.commit()
        assert s.query(type(row)).filter(type(row).status == "pending").count() == 1
