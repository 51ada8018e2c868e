"""Aircraft registry."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Query

from server.api.deps import Admin, Reader, SessionDep
from server.api.openapi import errors
from server.api.presenters import aircraft_read
from server.schemas import AircraftCreate, AircraftRead, Offset, Page
from server.services import fleet

router = APIRouter(prefix="/aircraft", tags=["aircraft"])


@router.post("", status_code=201, response_model=AircraftRead, responses=errors(409),
             summary="Register an aircraft with its three actuators (admin)")
def create(body: AircraftCreate, session: SessionDep, _: Admin) -> AircraftRead:
    row = fleet.create_aircraft(session=session, tail=body.tail, base=body.base,
                                serials=body.actuators.model_dump())
    session.commit()
    return aircraft_read(fleet.get_aircraft(session=session, tail=row.tail))


@router.get("", response_model=Page[AircraftRead], summary="List aircraft")
def list_(session: SessionDep, _: Reader,
          base: str | None = None,
          limit: Annotated[int, Query(ge=1, le=500)] = 100,
          offset: Offset = 0) -> Page[AircraftRead]:
    rows, total = fleet.list_aircraft(session=session, base=base, limit=limit, offset=offset)
    return Page(items=[aircraft_read(r) for r in rows], total=total, limit=limit, offset=offset)


@router.get("/{tail}", response_model=AircraftRead, summary="One aircraft")
def get(tail: str, session: SessionDep, _: Reader) -> AircraftRead:
    return aircraft_read(fleet.get_aircraft(session=session, tail=tail))
