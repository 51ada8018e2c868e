"""Maintenance actions on an actuator, as the fleet tools have them (fleet view -> alarm ->
action), each recorded in the actuator's audit trail with who, when and a work order:

* **replace**: the unit is removed and a new serial installed at its position. The new unit is
  a new row, so its health history, detection baseline (its own first flights), filter state
  and alarms start empty; the old unit's alarms are closed with the action (resolution
  ``replaced``) and, on the simulated half-wing, its injection ends.
* **inspect / no fault found**: the alarms are closed as false alarms (resolution
  ``no_fault_found``, the feedback record); the unit stays installed and monitored, its
  detector re-armed (``ActuatorHealth.rearm``: its own reference kept, the alarm latch, class
  evidence and filter cleared), so a fault that persists or returns raises a new alarm.
* **defer**: the open alarm is held (bucket ``deferred``) until the unit has flown N more
  flights or until a date, with a reason; then it is back in its own bucket, the expiry shown.
  A failed unit is never deferred.
"""

from __future__ import annotations

from datetime import datetime

from sqlalchemy import or_, select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from server.errors import Conflict, Unprocessable
from server.models import Actuator, ActuatorState, Alarm, ApiKey, MaintenanceAction, utcnow
from server.phm.chain import ActuatorHealth
from server.services.analysis import json_safe
from server.services.fleet import get_actuator
from server.services.health import close_alarms_of
from server.services.station import end_at as end_station_items_at
from server.vocabulary import AlarmStatus

__all__ = ["replace_actuator", "inspect_actuator", "defer_alarm", "audit_trail",
           "position_trail"]


def _record(session: Session, *, actuator: Actuator, kind: str, by: ApiKey, work_order: str,
            note: str | None, **fields: object) -> MaintenanceAction:
    row = MaintenanceAction(actuator_id=actuator.id, kind=kind, work_order=work_order,
                            performed_by=by.name, key_id=by.id, performed_at=utcnow(),
                            note=note, **fields)
    session.add(row)
    return row


def _installed(session: Session, actuator_id: int) -> Actuator:
    act = get_actuator(session=session, actuator_id=actuator_id)
    if act.removed_at is not None:
        raise Conflict(f"Actuator {actuator_id} was removed; act on the unit installed now.",
                       code="already_removed")
    return act


def replace_actuator(*, session: Session, actuator_id: int, new_serial: str, by: ApiKey,
                     work_order: str, note: str | None) -> tuple[Actuator, MaintenanceAction]:
    """Remove an installed actuator and install ``new_serial`` at its position."""
    old = _installed(session, actuator_id)
    if session.scalar(select(Actuator.id).where(Actuator.serial == new_serial,
                                                Actuator.removed_at.is_(None))) is not None:
        raise Conflict(f"Serial '{new_serial}' is installed elsewhere.", code="serial_in_use")
    old.removed_at = utcnow()
    old.removal_note = note or f"Replaced by {new_serial} ({work_order})."
    closed = close_alarms_of(session=session, actuator_id=old.id, by=by.name,
                             note=f"Replaced by {new_serial} ({work_order}).",
                             resolution="replaced")
    end_station_items_at(session=session, aircraft_id=old.aircraft_id, position=old.position)
    session.flush()
    new = Actuator(aircraft_id=old.aircraft_id, position=old.position, serial=new_serial)
    session.add(new)
    try:
        session.flush()
    except IntegrityError:
        raise Conflict("The actuator was replaced concurrently.", code="concurrent_change"
                       ) from None
    action = _record(session, actuator=old, kind="replace", by=by, work_order=work_order,
                     note=note, new_actuator_id=new.id, new_serial=new_serial,
                     closed_alarms=len(closed), alarm_id=closed[-1].id if closed else None)
    session.flush()
    session.refresh(new, attribute_names=["aircraft"])
    return new, action


def inspect_actuator(*, session: Session, actuator_id: int, by: ApiKey, work_order: str,
                     note: str | None) -> MaintenanceAction:
    """Inspection found no fault: close the unit's alarms as false alarms; keep monitoring."""
    act = _installed(session, actuator_id)
    if act.failed_at_flight is not None:
        raise Conflict(f"Actuator {actuator_id} failed at flight {act.failed_at_flight}; a "
                       "failed unit is replaced, not signed off.", code="actuator_failed")
    closed = close_alarms_of(session=session, actuator_id=act.id, by=by.name,
                             note=f"No fault found ({work_order})."
                             + (f" {note}" if note else ""), resolution="no_fault_found")
    if not closed:
        raise Conflict(f"Actuator {actuator_id} has no open alarm to inspect.",
                       code="no_open_alarm")
    _rearm(session, act.id)
    action = _record(session, actuator=act, kind="inspect", by=by, work_order=work_order,
                     note=note, closed_alarms=len(closed), alarm_id=closed[-1].id)
    session.flush()
    return action


def _rearm(session: Session, actuator_id: int) -> None:
    state = session.get(ActuatorState, actuator_id)
    if state is None or not (state.detection or {}).get("format"):
        return  # nothing analysed yet: nothing latched
    health = ActuatorHealth.from_dict(state.detection)
    health.rearm()
    doc = json_safe(health.to_dict())
    doc["confidence"] = state.detection.get("confidence", 0.0)
    state.detection = doc
    state.fault_mode = None


def defer_alarm(*, session: Session, actuator_id: int, by: ApiKey, work_order: str,
                reason: str, flights: int | None, until: datetime | None) -> MaintenanceAction:
    """Hold the unit's open alarm until it has flown ``flights`` more flights or until
    ``until`` (whichever comes first when both are given)."""
    if flights is None and until is None:
        raise Unprocessable("A deferral needs a number of flights or a date.",
                            code="deferral_unbounded")
    now = utcnow()
    if until is not None and until <= now:
        raise Unprocessable("The deferral's date is in the past.", code="deferral_in_past")
    act = _installed(session, actuator_id)
    if act.failed_at_flight is not None:
        raise Conflict(f"Actuator {actuator_id} failed at flight {act.failed_at_flight}; a "
                       "failed unit cannot be deferred.", code="actuator_failed")
    alarm = session.scalar(select(Alarm).where(Alarm.actuator_id == act.id,
                                               Alarm.status != AlarmStatus.CLOSED)
                           .order_by(Alarm.id.desc()).limit(1))
    if alarm is None:
        raise Conflict(f"Actuator {actuator_id} has no open alarm to defer.",
                       code="no_open_alarm")
    state = session.get(ActuatorState, act.id)
    seen = state.flights_seen if state else 0
    alarm.deferred_until_flight = None if flights is None else seen + flights
    alarm.deferred_until = until
    alarm.note = (alarm.note + "\n" if alarm.note else "") + f"Deferred ({work_order}): {reason}"
    action = _record(session, actuator=act, kind="defer", by=by, work_order=work_order,
                     note=reason, alarm_id=alarm.id,
                     defer_until_flight=alarm.deferred_until_flight, defer_until=until)
    session.flush()
    return action


def audit_trail(*, session: Session, actuator_id: int) -> list[MaintenanceAction]:
    """The actions on this unit and the replacement that installed it, oldest first."""
    get_actuator(session=session, actuator_id=actuator_id)  # 404 for an unknown one
    return list(session.scalars(select(MaintenanceAction).where(or_(
        MaintenanceAction.actuator_id == actuator_id,
        MaintenanceAction.new_actuator_id == actuator_id)).order_by(MaintenanceAction.id)))


def position_trail(*, session: Session, actuator_ids: list[int]) -> list[MaintenanceAction]:
    """The actions on every unit that has been at one position (the actuator page's trail),
    newest first."""
    if not actuator_ids:
        return []
    return list(session.scalars(select(MaintenanceAction).where(
        MaintenanceAction.actuator_id.in_(actuator_ids)).order_by(MaintenanceAction.id.desc())))
