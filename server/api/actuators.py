"""Actuators and the maintenance action that replaces one."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Query

from server.api.deps import Admin, Reader, SessionDep
from server.api.openapi import errors
from server.api.presenters import actuator_read
from server.schemas import ActuatorRead, ActuatorReplace, Page, Position
from server.services import fleet

router = APIRouter(prefix="/actuators", tags=["actuators"])


@router.get("", response_model=Page[ActuatorRead], summary="List actuators")
def list_(session: SessionDep, _: Reader,
          aircraft: str | None = None,
          position: Position | None = None,
          installed: bool | None = None,
          limit: Annotated[int, Query(ge=1, le=1000)] = 100,
          offset: Annotated[int, Query(ge=0)] = 0) -> Page[ActuatorRead]:
    rows, total = fleet.list_actuators(session=session, tail=aircraft, position=position,
                                       installed=installed, limit=limit, offset=offset)
    return Page(items=[actuator_read(r) for r in rows], total=total, limit=limit, offset=offset)


@router.get("/{actuator_id}", response_model=ActuatorRead, summary="One actuator")
def get(actuator_id: int, session: SessionDep, _: Reader) -> ActuatorRead:
    return actuator_read(fleet.get_actuator(session=session, actuator_id=actuator_id))


@router.post("/{actuator_id}/replace", status_code=201, response_model=ActuatorRead,
             responses=errors(409),
             summary="Maintenance: replace an installed actuator (admin); history starts again")
def replace(actuator_id: int, body: ActuatorReplace, session: SessionDep, _: Admin
            ) -> ActuatorRead:
    new = fleet.replace_actuator(session=session, actuator_id=actuator_id,
                                 new_serial=body.new_serial, note=body.note)
    session.commit()
    return actuator_read(fleet.get_actuator(session=session, actuator_id=new.id))
