"""Actuator health read-outs (records, prognoses, fleet grid) and the alarm workflow.

Alarm priority (stated so engineers can reason about the inbox order)::

    priority = confidence x criticality(mode) x (0.5 + urgency),  urgency = 1 / (1 + RUL50 / 50)

criticality reflects how fast a mode can end in a failure once detected: a MOSFET base-drive open
circuit (BDO) and a turn-to-turn short (TTS) evolve fastest (paper section 4.1), wear and
lubricant ageing slowest. RUL50 is the latest median RUL in flights (urgency 0.5 when unknown).
"""

from __future__ import annotations

from dataclasses import dataclass

from sqlalchemy import func, select
from sqlalchemy.orm import Session

from server.errors import Conflict, NotFound
from server.models import Actuator, ActuatorState, Aircraft, Alarm, HealthRecord, Prognosis, utcnow

__all__ = ["CRITICALITY", "alarm_priority", "list_alarms", "acknowledge_alarm", "close_alarm",
           "health_records", "prognoses", "fleet_grid", "GridCell", "close_alarms_of"]

CRITICALITY = {"BDO": 1.0, "TTS": 0.9, "DMD": 0.7, "SE": 0.6, "MTWEAR": 0.6, "REWEAR": 0.6,
               "MTEL": 0.5}


def alarm_priority(confidence: float, mode: str | None, rul_median: float | None) -> float:
    urgency = 0.5 if rul_median is None else 1.0 / (1.0 + max(rul_median, 0.0) / 50.0)
    return round(confidence * CRITICALITY.get(mode or "", 0.75) * (0.5 + urgency), 4)


def list_alarms(*, session: Session, status: str | None, tail: str | None, limit: int,
                offset: int) -> tuple[list[tuple[Alarm, Actuator, str]], int]:
    """Alarms with their actuator and tail, highest priority first."""
    query = (select(Alarm, Actuator, Aircraft.tail).join(Actuator, Alarm.actuator_id ==
                                                         Actuator.id).join(Aircraft))
    if status:
        query = query.where(Alarm.status == status)
    if tail:
        query = query.where(Aircraft.tail == tail)
    total = session.scalar(select(func.count()).select_from(query.subquery())) or 0
    rows = [(a, act, t) for a, act, t in session.execute(query).all()]
    rows.sort(key=lambda r: (r[0].status != "open",
                             -alarm_priority(r[0].confidence, r[0].fault_mode,
                                             r[0].rul_median_flights), -r[0].id))
    return rows[offset:offset + limit], total


def _alarm(session: Session, alarm_id: int) -> Alarm:
    row = session.get(Alarm, alarm_id)
    if row is None:
        raise NotFound(f"Alarm {alarm_id} does not exist.")
    return row


def acknowledge_alarm(*, session: Session, alarm_id: int, by: str, note: str | None) -> Alarm:
    row = _alarm(session, alarm_id)
    if row.status != "open":
        raise Conflict(f"Alarm {alarm_id} is {row.status}; only open alarms can be "
                       "acknowledged.", code="alarm_not_open")
    row.status, row.acknowledged_by, row.acknowledged_at = "acknowledged", by, utcnow()
    if note:
        row.note = note
    return row


def close_alarm(*, session: Session, alarm_id: int, by: str, note: str | None) -> Alarm:
    row = _alarm(session, alarm_id)
    if row.status == "closed":
        raise Conflict(f"Alarm {alarm_id} is already closed.", code="alarm_closed")
    row.status, row.closed_by, row.closed_at = "closed", by, utcnow()
    if note:
        row.note = (row.note + "\n" if row.note else "") + note
    return row


def close_alarms_of(*, session: Session, actuator_id: int, by: str, note: str) -> int:
    """Maintenance: close every open or acknowledged alarm of an actuator."""
    rows = session.scalars(select(Alarm).where(Alarm.actuator_id == actuator_id,
                                               Alarm.status != "closed")).all()
    for row in rows:
        row.status, row.closed_by, row.closed_at = "closed", by, utcnow()
        row.note = (row.note + "\n" if row.note else "") + note
    return len(rows)


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


def prognoses(*, session: Session, actuator_id: int, limit: int) -> list[Prognosis]:
    _actuator(session, actuator_id)
    rows = session.scalars(select(Prognosis).where(Prognosis.actuator_id == actuator_id)
                           .order_by(Prognosis.flight_index.desc()).limit(limit)).all()
    return list(reversed(rows))


@dataclass(frozen=True)
class GridCell:
    tail: str
    base: str
    position: str
    actuator_id: int
    serial: str
    status: str  # green | amber | red
    confidence: float
    fault_mode: str | None
    rul_median: float | None
    open_alarm_id: int | None
    flights_seen: int


def fleet_grid(*, session: Session, base: str | None = None) -> list[GridCell]:
    """One cell per installed actuator: green healthy, amber alarm, red alarm with RUL <= 25."""
    query = (select(Aircraft.tail, Aircraft.base, Actuator, ActuatorState)
             .join(Actuator, Actuator.aircraft_id == Aircraft.id)
             .outerjoin(ActuatorState, ActuatorState.actuator_id == Actuator.id)
             .where(Actuator.removed_at.is_(None)))
    if base:
        query = query.where(Aircraft.base == base)
    rows = session.execute(query.order_by(Aircraft.tail, Actuator.position)).all()
    alarms = {a.actuator_id: a for a in session.scalars(
        select(Alarm).where(Alarm.status != "closed").order_by(Alarm.id))}
    cells = []
    for tail, base_name, act, state in rows:
        alarm = alarms.get(act.id)
        det = (state.detection if state else {}) or {}
        rul = alarm.rul_median_flights if alarm else None
        if alarm is None:
            status = "green"
        elif rul is not None and rul <= 25:
            status = "red"
        else:
            status = "amber"
        cells.append(GridCell(tail=tail, base=base_name, position=act.position,
                              actuator_id=act.id, serial=act.serial, status=status,
                              confidence=float(det.get("confidence", 0.0)),
                              fault_mode=alarm.fault_mode if alarm else None, rul_median=rul,
                              open_alarm_id=alarm.id if alarm else None,
                              flights_seen=state.flights_seen if state else 0))
    return cells
