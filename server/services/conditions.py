"""Test station: simulation conditions on an aircraft, and what they did to each flight.

A condition (server.vocabulary.CONDITION_KINDS) is ``pending`` until the sim worker first flies
it (its first ground-truth report makes it ``active`` and records that flight as
``started_flight``), then lasts until an operator cancels it. It belongs to the aircraft, not
to an actuator, so replacing a unit leaves it live. One live condition of each kind per
aircraft: two load scales would compose in an order the operator did not choose; conditions
of different kinds compose (hotter air and larger loads on the same flights).
"""

from __future__ import annotations

from sqlalchemy import select
from sqlalchemy.orm import Session

from server.errors import Conflict, NotFound
from server.models import Aircraft, ConditionGroundTruth, SimCondition
from server.services.station_items import (
    add_live,
    applied_truths,
    cancel_live,
    page_with_tail,
    record_applied,
)
from server.vocabulary import STATION_LIVE

__all__ = ["create", "describe", "get", "list_", "cancel", "report_truth", "list_truth",
           "flights_under"]



def create(*, session: Session, tail: str, kind: str, value: float | None, base: str | None,
           onset_flight: int, created_by: str) -> SimCondition:
    aircraft = session.scalar(select(Aircraft).where(Aircraft.tail == tail))
    if aircraft is None:
        raise NotFound(f"Aircraft '{tail}' does not exist.")
    live = session.scalar(select(SimCondition).where(
        SimCondition.aircraft_id == aircraft.id, SimCondition.kind == kind,
        SimCondition.status.in_(STATION_LIVE)))
    if live is not None:
        raise Conflict(f"{tail} already has a live {kind} condition ({describe(live)}); "
                       "cancel it first.", code="condition_exists",
                       details={"condition_id": live.id})
    row = SimCondition(aircraft_id=aircraft.id, kind=kind, value=value, base=base,
                       onset_flight=onset_flight, created_by=created_by, status="pending")
    return add_live(session, row, lambda: Conflict(
        f"{tail} was given a live {kind} condition concurrently; cancel it first.",
        code="condition_exists"))


def describe(row: SimCondition) -> str:
    """The condition in a few words, e.g. ``load_scale 1.5`` or ``base Abu Dhabi``."""
    return f"{row.kind} {row.base if row.kind == 'base' else format(row.value, 'g')}"


def get(*, session: Session, condition_id: int) -> SimCondition:
    row = session.get(SimCondition, condition_id)
    if row is None:
        raise NotFound(f"Condition {condition_id} does not exist.")
    return row


def list_(*, session: Session, tail: str | None, status: str | None, limit: int, offset: int
          ) -> tuple[list[tuple[SimCondition, str]], int]:
    return page_with_tail(session=session, model=SimCondition, tail=tail, status=status,
                          limit=limit, offset=offset)


def cancel(*, session: Session, condition_id: int) -> SimCondition:
    return cancel_live(get(session=session, condition_id=condition_id),
                       f"Condition {condition_id}")


def report_truth(*, session: Session, condition_id: int, flight_code: str, flight_number: int,
                 applied: float) -> ConditionGroundTruth:
    """Record (idempotently) what the condition did to one flight; the first report makes a
    pending condition active from that flight."""
    return record_applied(session, get(session=session, condition_id=condition_id),
                          ConditionGroundTruth, "condition_id", flight_code=flight_code,
                          flight_number=flight_number, applied=applied)


def list_truth(*, session: Session, condition_id: int) -> list[ConditionGroundTruth]:
    get(session=session, condition_id=condition_id)  # 404 for an unknown one
    return applied_truths(session, ConditionGroundTruth, "condition_id", condition_id)


def flights_under(*, session: Session, aircraft_id: int) -> dict[str, list[SimCondition]]:
    """Flight code -> the conditions it was flown under (its ground truth), for the pages."""
    rows = session.execute(select(ConditionGroundTruth.flight_code, SimCondition).join(
        SimCondition, SimCondition.id == ConditionGroundTruth.condition_id).where(
        SimCondition.aircraft_id == aircraft_id).order_by(SimCondition.id)).all()
    out: dict[str, list[SimCondition]] = {}
    for code, condition in rows:
        out.setdefault(code, []).append(condition)
    return out
