"""Actuator health read-outs (records, prognoses, fleet grid) and the alarm workflow.

Inbox order and the grid's colours follow one rule, :func:`server.services.urgency.urgency`
(buckets: replace now, act within N flights, monitor, deferred, healthy), never a decimal.
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import datetime
from typing import Any

from sqlalchemy import func, select
from sqlalchemy.orm import Session

from server.errors import Conflict, NotFound
from server.models import (
    Actuator,
    ActuatorState,
    Aircraft,
    Alarm,
    AlarmEvent,
    HealthRecord,
    Prognosis,
    utcnow,
)
from server.schemas import GridCellRead
from server.services.urgency import Urgency, deferral_active, sort_key, urgency
from server.vocabulary import WINGLET_PAIR, AlarmStatus

__all__ = ["alarm_urgency", "list_alarms", "acknowledge_alarm", "close_alarm",
           "health_records", "prognoses", "fleet_grid", "close_alarms_of",
           "AlarmRow", "actuator_urgency", "pair_winglet_alarms", "winglet_partner_alarm",
           "remaining_life", "current_prognoses", "alarm_events", "get_alarm",
           "SensorFlight", "sensor_findings"]


def remaining_life(actuator: Actuator, rul_flights: float | None) -> float | None:
    """An RUL read-out of a unit: none left (0 flights) once it has failed, whatever its last
    prediction said; otherwise the prediction."""
    return 0.0 if actuator.failed_at_flight is not None else rul_flights


@dataclass(frozen=True)
class AlarmRow:
    alarm: Alarm
    actuator: Actuator
    tail: str
    urgency: Urgency | None  # None once the alarm is closed: it claims no live urgency
    deferral_expired: bool  # a deferral was set and has run out

    @property
    def rul_median(self) -> float | None:
        return remaining_life(self.actuator, self.alarm.rul_median_flights)

    @property
    def rul_low(self) -> float | None:
        return remaining_life(self.actuator, self.alarm.rul_low_flights)


def alarm_urgency(alarm: Alarm, actuator: Actuator, flights_seen: int,
                  now: datetime | None = None) -> tuple[Urgency | None, bool]:
    """(the alarm's bucket, None once it is closed; whether a deferral it had has expired)."""
    if alarm.status == AlarmStatus.CLOSED:
        return None, False
    return _open_alarm_urgency(alarm, actuator, flights_seen, now)


def _open_alarm_urgency(alarm: Alarm, actuator: Actuator, flights_seen: int,
                        now: datetime | None = None) -> tuple[Urgency, bool]:
    had = alarm.deferred_until_flight is not None or alarm.deferred_until is not None
    active = deferral_active(
        until_flight=alarm.deferred_until_flight, until=alarm.deferred_until,
        flights_seen=flights_seen, now=now or utcnow())
    u = urgency(failed_at_flight=actuator.failed_at_flight, alarm_open=True,
                fault_mode=alarm.fault_mode, rul_low_flights=alarm.rul_low_flights,
                deferred=active)
    return u, had and not active


def _inbox_order(row: AlarmRow) -> tuple[bool, int, float, float, int]:
    """Not closed first, most urgent first (the urgency rule); closed ones newest first."""
    if row.urgency is None:
        return (True, 0, 0.0, 0.0, -row.alarm.id)
    return (False, *sort_key(row.urgency, row.alarm.confidence), -row.alarm.id)


def list_alarms(*, session: Session, status: str | None, tail: str | None, limit: int,
                offset: int) -> tuple[list[AlarmRow], int]:
    """Alarms with their actuator, tail and urgency; not closed first, most urgent first."""
    query = (select(Alarm, Actuator, Aircraft.tail, ActuatorState.flights_seen)
             .join(Actuator, Alarm.actuator_id == Actuator.id).join(Aircraft)
             .outerjoin(ActuatorState, ActuatorState.actuator_id == Actuator.id))
    if status:
        query = query.where(Alarm.status == status)
    if tail:
        query = query.where(Aircraft.tail == tail)
    total = session.scalar(select(func.count()).select_from(query.subquery())) or 0
    now = utcnow()
    rows = []
    for a, act, t, seen in session.execute(query).all():
        u, expired = alarm_urgency(a, act, seen or 0, now)
        rows.append(AlarmRow(a, act, t, u, expired))
    rows.sort(key=_inbox_order)
    return rows[offset:offset + limit], total


def _pair_key(row: AlarmRow) -> tuple[str, str | None] | None:
    a = row.alarm
    if (a.status == AlarmStatus.CLOSED or row.actuator.position not in WINGLET_PAIR
            or not a.fault_mode):
        return None
    return row.tail, a.fault_mode


def pair_winglet_alarms(rows: list[AlarmRow]) -> list[tuple[AlarmRow, AlarmRow | None]]:
    """The inbox's rows with the two drives of a winglet pair merged into one: open alarms of
    WL1 and WL2 of one aircraft in the same mode are one fault of the pair whose evidence does
    not tell the drives apart (the rod-end feature is their LVDT difference; both drives move
    one tab). The more urgent row leads (the order of ``rows`` is kept)."""
    first: dict[tuple[str, str | None], int] = {}
    out: list[tuple[AlarmRow, AlarmRow | None]] = []
    for row in rows:
        key = _pair_key(row)
        if key is not None and key in first and out[first[key]][1] is None \
                and out[first[key]][0].actuator.position != row.actuator.position:
            out[first[key]] = (out[first[key]][0], row)
            continue
        if key is not None:
            first.setdefault(key, len(out))
        out.append((row, None))
    return out


def winglet_partner_alarm(*, session: Session, alarm_id: int) -> tuple[Alarm, Actuator] | None:
    """The not-closed alarm in the same mode on the other drive of the winglet pair, if any."""
    alarm = _alarm(session, alarm_id)
    actuator = session.get(Actuator, alarm.actuator_id)
    if (actuator is None or actuator.position not in WINGLET_PAIR
            or alarm.status == AlarmStatus.CLOSED or not alarm.fault_mode):
        return None
    other = next(p for p in WINGLET_PAIR if p != actuator.position)
    found = session.execute(
        select(Alarm, Actuator).join(Actuator, Alarm.actuator_id == Actuator.id)
        .where(Actuator.aircraft_id == actuator.aircraft_id, Actuator.position == other,
               Actuator.removed_at.is_(None), Alarm.status != AlarmStatus.CLOSED,
               Alarm.fault_mode == alarm.fault_mode)
        .order_by(Alarm.id.desc()).limit(1)).first()
    return None if found is None else (found[0], found[1])


def get_alarm(*, session: Session, alarm_id: int) -> Alarm:
    row = session.get(Alarm, alarm_id)
    if row is None:
        raise NotFound(f"Alarm {alarm_id} does not exist.")
    return row


def alarm_row(*, session: Session, alarm_id: int) -> AlarmRow:
    """One alarm as the inbox shows it (actuator, tail, urgency); 404 for an unknown one."""
    alarm = get_alarm(session=session, alarm_id=alarm_id)
    actuator = _actuator(session, alarm.actuator_id)
    state = session.get(ActuatorState, actuator.id)
    u, expired = alarm_urgency(alarm, actuator, state.flights_seen if state else 0)
    return AlarmRow(alarm, actuator, actuator.aircraft.tail, u, expired)


def _alarm(session: Session, alarm_id: int) -> Alarm:
    return get_alarm(session=session, alarm_id=alarm_id)


def acknowledge_alarm(*, session: Session, alarm_id: int, by: str, note: str | None) -> Alarm:
    row = _alarm(session, alarm_id)
    if row.status != AlarmStatus.OPEN:
        raise Conflict(f"Alarm {alarm_id} is {row.status}; only open alarms can be "
                       "acknowledged.", code="alarm_not_open")
    row.status, row.acknowledged_by, row.acknowledged_at = AlarmStatus.ACKNOWLEDGED, by, utcnow()
    if note:
        row.note = note
    return row


def close_alarm(*, session: Session, alarm_id: int, by: str, note: str | None) -> Alarm:
    row = _alarm(session, alarm_id)
    if row.status == AlarmStatus.CLOSED:
        raise Conflict(f"Alarm {alarm_id} is already closed.", code="alarm_closed")
    row.status, row.closed_by, row.closed_at = AlarmStatus.CLOSED, by, utcnow()
    row.resolution = "closed"
    if note:
        row.note = (row.note + "\n" if row.note else "") + note
    return row


def close_alarms_of(*, session: Session, actuator_id: int, by: str, note: str,
                    resolution: str = "closed") -> list[Alarm]:
    """Maintenance: close every open or acknowledged alarm of an actuator, with how."""
    rows = list(session.scalars(select(Alarm).where(Alarm.actuator_id == actuator_id,
                                                    Alarm.status != AlarmStatus.CLOSED)
                                .order_by(Alarm.id)))
    for row in rows:
        row.status, row.closed_by, row.closed_at = AlarmStatus.CLOSED, by, utcnow()
        row.resolution = resolution
        row.deferred_until_flight = row.deferred_until = None
        row.note = (row.note + "\n" if row.note else "") + note
    return rows


def _actuator(session: Session, actuator_id: int) -> Actuator:
    row = session.get(Actuator, actuator_id)
    if row is None:
        raise NotFound(f"Actuator {actuator_id} does not exist.")
    return row


def health_records(*, session: Session, actuator_id: int, limit: int) -> list[HealthRecord]:
    _actuator(session, actuator_id)
    rows = session.scalars(select(HealthRecord).where(HealthRecord.actuator_id == actuator_id)
                           .order_by(HealthRecord.flight_index.desc()).limit(limit)).all()
    return list(reversed(rows))


@dataclass(frozen=True)
class SensorFlight:
    """The sensor findings of one analysed flight of an actuator."""

    flight_id: int
    flight_index: int
    started_at: datetime | None
    findings: list[dict[str, Any]]
    set_aside: list[str]
    widened: dict[str, float]
    outside_design: list[dict[str, Any]]


def sensor_findings(*, session: Session, actuator_id: int, limit: int) -> list[SensorFlight]:
    """The actuator's flights with a sensor finding or a condition outside the design among
    its latest ``limit`` analysed flights, oldest first."""
    out = []
    for r in health_records(session=session, actuator_id=actuator_id, limit=limit):
        scores = r.scores or {}
        if scores.get("sensor_findings") or scores.get("outside_design"):
            out.append(SensorFlight(r.flight_id, r.flight_index, r.started_at,
                                    list(scores.get("sensor_findings") or []),
                                    list(scores.get("set_aside") or []),
                                    dict(scores.get("widened") or {}),
                                    list(scores.get("outside_design") or [])))
    return out


def prognoses(*, session: Session, actuator_id: int, limit: int) -> list[Prognosis]:
    _actuator(session, actuator_id)
    rows = session.scalars(select(Prognosis).where(Prognosis.actuator_id == actuator_id)
                           .order_by(Prognosis.flight_index.desc()).limit(limit)).all()
    return list(reversed(rows))


def current_prognoses(*, session: Session, actuator_id: int, limit: int) -> list[Prognosis]:
    """The prognoses that speak for the unit now: those made since its latest alarm was
    raised; none when that alarm was closed as no fault found (until a new alarm)."""
    latest = session.scalar(select(Alarm).where(Alarm.actuator_id == actuator_id)
                            .order_by(Alarm.id.desc()).limit(1))
    if latest is None or latest.resolution == "no_fault_found":
        _actuator(session, actuator_id)
        return []
    since = session.scalar(select(HealthRecord.flight_index).where(
        HealthRecord.actuator_id == actuator_id, HealthRecord.flight_id == latest.flight_id))
    rows = prognoses(session=session, actuator_id=actuator_id, limit=limit)
    return [p for p in rows if since is None or p.flight_index >= since]


def alarm_events(*, session: Session, alarm_ids: list[int]) -> list[AlarmEvent]:
    """What happened to these alarms after they were raised (leading-class changes), oldest
    first."""
    if not alarm_ids:
        return []
    return list(session.scalars(select(AlarmEvent).where(AlarmEvent.alarm_id.in_(alarm_ids))
                                .order_by(AlarmEvent.id)))


def actuator_urgency(*, session: Session, actuator: Actuator) -> tuple[Urgency, Alarm | None,
                                                                        bool]:
    """One actuator's bucket, its latest not-closed alarm and whether a deferral expired."""
    state = session.get(ActuatorState, actuator.id)
    alarm = session.scalar(select(Alarm).where(Alarm.actuator_id == actuator.id,
                                               Alarm.status != AlarmStatus.CLOSED)
                           .order_by(Alarm.id.desc()).limit(1))
    if alarm is None:
        return urgency(failed_at_flight=actuator.failed_at_flight, alarm_open=False,
                       fault_mode=None, rul_low_flights=None), None, False
    u, expired = _open_alarm_urgency(alarm, actuator, state.flights_seen if state else 0)
    return u, alarm, expired


def fleet_grid(*, session: Session, base: str | None = None) -> list[GridCellRead]:
    """One cell per installed actuator, coloured by its urgency bucket
    (:mod:`server.services.urgency`). The API's schema is the cell itself: the dashboard's
    fleet page and ``GET /fleet/health`` show the one structure."""
    query = (select(Aircraft.tail, Aircraft.base, Actuator, ActuatorState)
             .join(Actuator, Actuator.aircraft_id == Aircraft.id)
             .outerjoin(ActuatorState, ActuatorState.actuator_id == Actuator.id)
             .where(Actuator.removed_at.is_(None)))
    if base:
        query = query.where(Aircraft.base == base)
    rows = session.execute(query.order_by(Aircraft.tail, Actuator.position)).all()
    alarms = {a.actuator_id: a for a in session.scalars(
        select(Alarm).where(Alarm.status != AlarmStatus.CLOSED).order_by(Alarm.id))}
    now = utcnow()
    cells = []
    for tail, base_name, act, state in rows:
        alarm = alarms.get(act.id)
        det = (state.detection if state else {}) or {}
        seen = state.flights_seen if state else 0
        if alarm is None:
            u = urgency(failed_at_flight=act.failed_at_flight, alarm_open=False,
                        fault_mode=None, rul_low_flights=None)
        else:
            u, _ = _open_alarm_urgency(alarm, act, seen, now)
        cells.append(GridCellRead(tail=tail, base=base_name, position=act.position,
                                  actuator_id=act.id, serial=act.serial, status=u.colour,
                                  urgency=u.bucket, urgency_label=u.label,
                                  act_within_flights=u.within_flights,
                                  failed_at_flight=act.failed_at_flight,
                                  confidence=float(det.get("confidence", 0.0)),
                                  fault_mode=alarm.fault_mode if alarm else None,
                                  rul_median=remaining_life(
                                      act, alarm.rul_median_flights if alarm else None),
                                  rul_low=remaining_life(
                                      act, alarm.rul_low_flights if alarm else None),
                                  open_alarm_id=alarm.id if alarm else None,
                                  flights_seen=seen,
                                  sensor_findings=list(det.get("sensor_findings") or []),
                                  outside_design=list(det.get("outside_design") or [])))
    return cells
