"""Test station: sensor injections into simulated actuators, and what they did to each flight.

A sensor injection is ``pending`` until the sim worker first flies it (its first ground-truth
report makes it ``active`` and records that flight as ``started_flight``), then lasts until an
operator cancels it. Replacing the actuator cancels it too: the new unit's sensors are sound.
One live injection per actuator sensor (position and sensor); it may fly beside a fault
injection on the same actuator, as a worn sensor may sit on a degrading drive.
"""

from __future__ import annotations

from sqlalchemy import select
from sqlalchemy.orm import Session

from server.errors import Conflict, NotFound
from server.models import Aircraft, SensorGroundTruth, SensorInjection, utcnow
from server.services.station_items import (
    add_live,
    applied_truths,
    cancel_live,
    page_with_tail,
    record_applied,
)
from server.vocabulary import STATION_LIVE

__all__ = ["create", "get", "list_", "cancel", "report_truth", "list_truth", "end_at"]



def create(*, session: Session, tail: str, position: str, sensor: str, kind: str, value: float,
           onset_flight: int, created_by: str) -> SensorInjection:
    aircraft = session.scalar(select(Aircraft).where(Aircraft.tail == tail))
    if aircraft is None:
        raise NotFound(f"Aircraft '{tail}' does not exist.")
    live = session.scalar(select(SensorInjection).where(
        SensorInjection.aircraft_id == aircraft.id, SensorInjection.position == position,
        SensorInjection.sensor == sensor, SensorInjection.status.in_(STATION_LIVE)))
    if live is not None:
        # two transforms of one sensor would compose in an order the operator did not choose
        raise Conflict(f"The {sensor} of {tail} {position} already has a live sensor injection "
                       f"({live.kind}); cancel it first.", code="sensor_injection_exists",
                       details={"sensor_injection_id": live.id})
    row = SensorInjection(aircraft_id=aircraft.id, position=position, sensor=sensor, kind=kind,
                          value=value, onset_flight=onset_flight, created_by=created_by,
                          status="pending")
    return add_live(session, row, lambda: Conflict(
        f"The {sensor} of {tail} {position} was given a live sensor injection concurrently; "
        "cancel it first.", code="sensor_injection_exists"))


def get(*, session: Session, injection_id: int) -> SensorInjection:
    row = session.get(SensorInjection, injection_id)
    if row is None:
        raise NotFound(f"Sensor injection {injection_id} does not exist.")
    return row


def list_(*, session: Session, tail: str | None, status: str | None, limit: int, offset: int
          ) -> tuple[list[tuple[SensorInjection, str]], int]:
    return page_with_tail(session=session, model=SensorInjection, tail=tail, status=status,
                          limit=limit, offset=offset)


def cancel(*, session: Session, injection_id: int) -> SensorInjection:
    return cancel_live(get(session=session, injection_id=injection_id),
                       f"Sensor injection {injection_id}")


def report_truth(*, session: Session, injection_id: int, flight_code: str, flight_number: int,
                 applied: float) -> SensorGroundTruth:
    """Record (idempotently) what the injection did to one flight; the first report makes a
    pending injection active from that flight."""
    return record_applied(session, get(session=session, injection_id=injection_id),
                          SensorGroundTruth, "sensor_injection_id", flight_code=flight_code,
                          flight_number=flight_number, applied=applied)


def list_truth(*, session: Session, injection_id: int) -> list[SensorGroundTruth]:
    get(session=session, injection_id=injection_id)  # 404 for an unknown one
    return applied_truths(session, SensorGroundTruth, "sensor_injection_id", injection_id)


def end_at(*, session: Session, aircraft_id: int, position: str) -> list[SensorInjection]:
    """The actuator at ``position`` was replaced: its live sensor injections are cancelled."""
    rows = list(session.scalars(select(SensorInjection).where(
        SensorInjection.aircraft_id == aircraft_id, SensorInjection.position == position,
        SensorInjection.status.in_(STATION_LIVE))))
    now = utcnow()
    for row in rows:
        row.status, row.cancelled_at = "cancelled", now
    return rows
