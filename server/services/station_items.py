"""What the test station's three kinds of item share (fault injections, sensor injections,
conditions): the states in which one is live, a page of them with their aircraft's tail,
cancelling a live one, and (for sensor injections and conditions) the value each applied to a
flight, as the sim worker reports it."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar

from sqlalchemy import func, select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from server.errors import Conflict
from server.models import Aircraft, utcnow
from server.vocabulary import STATION_LIVE

__all__ = ["add_live", "page_with_tail", "cancel_live", "record_applied", "applied_truths"]

Item = TypeVar("Item")
Truth = TypeVar("Truth")


def page_with_tail(*, session: Session, model: type[Item], tail: str | None,
                   status: str | None, limit: int, offset: int
                   ) -> tuple[list[tuple[Item, str]], int]:
    """Items of ``model`` (newest first) with their aircraft's tail, and how many there are,
    optionally of one aircraft and one status."""
    table: Any = model  # a mapped class with aircraft_id, status and id
    query = select(table, Aircraft.tail).join(Aircraft)
    if tail:
        query = query.where(Aircraft.tail == tail)
    if status:
        query = query.where(table.status == status)
    total = session.scalar(select(func.count()).select_from(query.subquery())) or 0
    rows = session.execute(query.order_by(table.id.desc()).limit(limit).offset(offset)).all()
    return [(r[0], r[1]) for r in rows], total


def cancel_live(row: Item, what: str) -> Item:
    """``row`` cancelled now; a 409 ``not_live`` naming ``what`` if it is not live."""
    item: Any = row
    if item.status not in STATION_LIVE:
        raise Conflict(f"{what} is {item.status}; only pending or active ones can be "
                       "cancelled.", code="not_live")
    item.status = "cancelled"
    item.cancelled_at = utcnow()
    return row


def add_live(session: Session, row: Item, conflict: Callable[[], Conflict]) -> Item:
    """``row`` (a new live item) added and flushed; ``conflict()`` raised if a concurrent
    request made a live item in the same slot first (the database's partial unique index)."""
    session.add(row)
    try:
        session.flush()
    except IntegrityError:
        raise conflict() from None
    return row


def record_applied(session: Session, item: Any, truth: type[Truth], item_key: str, *,
                   flight_code: str, flight_number: int, applied: float) -> Truth:
    """Record (idempotently) the value ``item`` applied to one flight, as a row of ``truth``
    whose ``item_key`` column names the item; the first report makes a pending item active
    from that flight."""
    if item.status == "pending":
        item.status = "active"
        item.started_flight = flight_number
    table: Any = truth  # a mapped class with item_key, flight_code, flight_number, applied
    row = session.scalar(select(table).where(getattr(table, item_key) == item.id,
                                             table.flight_code == flight_code))
    if row is None:
        row = table(**{item_key: item.id, "flight_code": flight_code})
        session.add(row)
    row.flight_number = flight_number
    row.applied = applied
    session.flush()
    return row


def applied_truths(session: Session, truth: type[Truth], item_key: str, item_id: int
                   ) -> list[Truth]:
    """The values one item applied, flight by flight."""
    table: Any = truth
    return list(session.scalars(select(table).where(getattr(table, item_key) == item_id)
                                .order_by(table.flight_number)))
