"""Actuators and the maintenance actions on them (replace, inspect / no fault found, defer),
with their audit trail. Maintenance actions need the maintainer or admin role."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Query

from server.api.deps import Maintainer, Reader, SessionDep
from server.api.openapi import errors
from server.api.presenters import actuator_read
from server.schemas import (
    ActuatorDefer,
    ActuatorInspect,
    ActuatorRead,
    ActuatorReplace,
    IdPath,
    MaintenanceActionRead,
    Offset,
    Page,
    Position,
)
from server.services import fleet, maintenance

router = APIRouter(prefix="/actuators", tags=["actuators"])


@router.get("", response_model=Page[ActuatorRead], summary="List actuators")
def list_(session: SessionDep, _: Reader,
          aircraft: str | None = None,
          position: Position | None = None,
          installed: bool | None = None,
          limit: Annotated[int, Query(ge=1, le=1000)] = 100,
          offset: Offset = 0) -> Page[ActuatorRead]:
    rows, total = fleet.list_actuators(session=session, tail=aircraft, position=position,
                                       installed=installed, limit=limit, offset=offset)
    return Page(items=[actuator_read(r) for r in rows], total=total, limit=limit, offset=offset)


@router.get("/{actuator_id}", response_model=ActuatorRead, summary="One actuator")
def get(actuator_id: IdPath, session: SessionDep, _: Reader) -> ActuatorRead:
    return actuator_read(fleet.get_actuator(session=session, actuator_id=actuator_id))


@router.post("/{actuator_id}/replace", status_code=201, response_model=ActuatorRead,
             responses=errors(409),
             summary="Maintenance: replace an installed actuator (maintainer/admin); the new "
                     "unit's history starts again, the old one's alarms close")
def replace(actuator_id: IdPath, body: ActuatorReplace, session: SessionDep, key: Maintainer
            ) -> ActuatorRead:
    new, _ = maintenance.replace_actuator(session=session, actuator_id=actuator_id,
                                          new_serial=body.new_serial, by=key,
                                          work_order=body.work_order, note=body.note)
    session.commit()
    return actuator_read(fleet.get_actuator(session=session, actuator_id=new.id))


@router.post("/{actuator_id}/inspect", status_code=201, response_model=MaintenanceActionRead,
             responses=errors(409),
             summary="Maintenance: inspected, no fault found (maintainer/admin); the alarms "
                     "close as false alarms, monitoring goes on")
def inspect(actuator_id: IdPath, body: ActuatorInspect, session: SessionDep, key: Maintainer
            ) -> MaintenanceActionRead:
    row = maintenance.inspect_actuator(session=session, actuator_id=actuator_id, by=key,
                                       work_order=body.work_order, note=body.note)
    session.commit()
    return MaintenanceActionRead.model_validate(row)


@router.post("/{actuator_id}/defer", status_code=201, response_model=MaintenanceActionRead,
             responses=errors(409),
             summary="Maintenance: defer the open alarm for N flights or until a date "
                     "(maintainer/admin)")
def defer(actuator_id: IdPath, body: ActuatorDefer, session: SessionDep, key: Maintainer
          ) -> MaintenanceActionRead:
    row = maintenance.defer_alarm(session=session, actuator_id=actuator_id, by=key,
                                  work_order=body.work_order, reason=body.reason,
                                  flights=body.flights, until=body.until)
    session.commit()
    return MaintenanceActionRead.model_validate(row)


@router.get("/{actuator_id}/maintenance", response_model=list[MaintenanceActionRead],
            summary="Audit trail: the maintenance actions on this unit (and the replacement "
                    "that installed it), oldest first")
def trail(actuator_id: IdPath, session: SessionDep, _: Reader) -> list[MaintenanceActionRead]:
    return [MaintenanceActionRead.model_validate(r)
            for r in maintenance.audit_trail(session=session, actuator_id=actuator_id)]
