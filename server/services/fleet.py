"""Fleet registry: aircraft and the actuators installed on them (maintenance actions:
:mod:`server.services.maintenance`)."""

from __future__ import annotations

from sqlalchemy import func, select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session, selectinload

from server.errors import Conflict, NotFound
from server.flightlog import POSITIONS
from server.models import Actuator, Aircraft

__all__ = ["create_aircraft", "get_aircraft", "list_aircraft", "tail_of", "installed_serials",
           "get_actuator", "list_actuators"]


def create_aircraft(*, session: Session, tail: str, base: str, serials: dict[str, str]) -> Aircraft:
    if session.scalar(select(Aircraft.id).where(Aircraft.tail == tail)) is not None:
        raise Conflict(f"Aircraft '{tail}' already exists.", code="aircraft_exists")
    taken = session.scalars(select(Actuator.serial).where(
        Actuator.serial.in_(serials.values()), Actuator.removed_at.is_(None))).all()
    if taken:
        raise Conflict("Actuator serial(s) already installed elsewhere: " + ", ".join(taken) + ".",
                       code="serial_in_use", details={"serials": list(taken)})
    aircraft = Aircraft(tail=tail, base=base)
    session.add(aircraft)
    for position in POSITIONS:
        session.add(Actuator(aircraft=aircraft, position=position, serial=serials[position]))
    try:
        session.flush()
    except IntegrityError:  # a concurrent request registered the same tail or serial
        raise Conflict(f"Aircraft '{tail}' or one of its serials was registered concurrently.",
                       code="aircraft_exists") from None
    return aircraft


def get_aircraft(*, session: Session, tail: str) -> Aircraft:
    aircraft = session.scalar(select(Aircraft).where(Aircraft.tail == tail)
                              .options(selectinload(Aircraft.actuators)))
    if aircraft is None:
        raise NotFound(f"Aircraft '{tail}' does not exist.")
    return aircraft


def list_aircraft(*, session: Session, base: str | None, limit: int, offset: int
                  ) -> tuple[list[Aircraft], int]:
    query = select(Aircraft)
    if base:
        query = query.where(Aircraft.base == base)
    total = session.scalar(select(func.count()).select_from(query.subquery())) or 0
    rows = session.scalars(query.order_by(Aircraft.tail).limit(limit).offset(offset)
                           .options(selectinload(Aircraft.actuators))).all()
    return list(rows), total


def tail_of(*, session: Session, aircraft_id: int) -> str:
    """The tail of a registered aircraft (the rows that point at it are kept by foreign key)."""
    aircraft = session.get(Aircraft, aircraft_id)
    if aircraft is None:
        raise NotFound(f"Aircraft {aircraft_id} does not exist.")
    return aircraft.tail


def installed_serials(*, session: Session, tail: str) -> dict[str, str] | None:
    """Position -> serial of the actuators installed now, or None for an unknown aircraft."""
    aircraft_id = session.scalar(select(Aircraft.id).where(Aircraft.tail == tail))
    if aircraft_id is None:
        return None
    rows = session.execute(select(Actuator.position, Actuator.serial).where(
        Actuator.aircraft_id == aircraft_id, Actuator.removed_at.is_(None))).all()
    return {p: s for p, s in rows}


def get_actuator(*, session: Session, actuator_id: int) -> Actuator:
    actuator = session.get(Actuator, actuator_id, options=[selectinload(Actuator.aircraft)])
    if actuator is None:
        raise NotFound(f"Actuator {actuator_id} does not exist.")
    return actuator


def list_actuators(*, session: Session, tail: str | None, position: str | None,
                   installed: bool | None, limit: int, offset: int
                   ) -> tuple[list[Actuator], int]:
    query = select(Actuator).join(Aircraft)
    if tail:
        query = query.where(Aircraft.tail == tail)
    if position:
        query = query.where(Actuator.position == position)
    if installed is not None:
        query = query.where(Actuator.removed_at.is_(None) if installed
                            else Actuator.removed_at.is_not(None))
    total = session.scalar(select(func.count()).select_from(query.subquery())) or 0
    rows = session.scalars(query.order_by(Aircraft.tail, Actuator.position, Actuator.id)
                           .limit(limit).offset(offset)
                           .options(selectinload(Actuator.aircraft))).all()
    return list(rows), total
