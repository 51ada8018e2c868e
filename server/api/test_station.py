"""Test station: operators schedule faults, sensor faults and conditions on simulated aircraft;
the simulator takes each flight's plan and reports what it flew.

The routes of every kind (``/test-station/<kind>``: create, list, one, cancel, its truth) are
made from the registry ``server.services.station.KINDS``, each with its own body and read model
in the OpenAPI; ``POST /test-station/items`` creates any kind from one body, a union discriminated
by ``station_kind`` (the kind's key); the flight plan and the flight's report serve all kinds at
once."""

from __future__ import annotations

import inspect
from collections.abc import Callable
from typing import Annotated, Any, Literal, Union

from fastapi import APIRouter, Path, Query
from pydantic import BaseModel, ConfigDict, Field, create_model

from server.api.deps import Operator, Reader, SessionDep
from server.api.openapi import errors
from server.api.presenters import aircraft_read
from server.flightlog import ID_PATTERN, MAX_ID_LEN
from server.models import ApiKey
from server.schemas import (
    MAX_INT32,
    AircraftRead,
    FlightNumber,
    Identifier,
    IdPath,
    InjectionRead,
    InjectionStatus,
    Offset,
    Page,
)
from server.services import fleet, station, station_faults
from server.services.station import FAULTS, KINDS, Kind

router = APIRouter(prefix="/test-station", tags=["test station"])

FlightPath = Annotated[str, Path(pattern=ID_PATTERN, max_length=MAX_ID_LEN)]


def item_read(kind: Kind, row: Any, tail: str, **more: Any) -> BaseModel:
    """An item as the API shows it: its columns, its aircraft's tail, what its kind derives."""
    fields = {name: getattr(row, name) for name in kind.read.model_fields if hasattr(row, name)}
    return kind.read.model_validate({**fields, "aircraft": tail, **kind.derived(row), **more})


def truth_read(kind: Kind, row: Any) -> BaseModel:
    return kind.truth_read.model_validate({
        kind.truth_key: getattr(row, kind.truth_key), "flight": row.flight_code,
        "flight_number": row.flight_number,
        **{name: getattr(row, name) for name in kind.truth_fields}})


def _typed(endpoint: Callable[..., Any], **annotations: Any) -> Callable[..., Any]:
    """``endpoint`` with its parameters' types replaced (FastAPI reads the body's schema from
    the signature; a route made per kind has its kind's)."""
    signature = inspect.signature(endpoint)
    endpoint.__signature__ = signature.replace(parameters=[  # type: ignore[attr-defined]
        p.replace(annotation=annotations.get(p.name, p.annotation))
        for p in signature.parameters.values()])
    return endpoint


def _tail(session: SessionDep, row: Any) -> str:
    return fleet.tail_of(session=session, aircraft_id=row.aircraft_id)


def _create(kind: Kind, spec: Any, session: SessionDep, key: ApiKey) -> BaseModel:
    """A new item of ``kind`` from its create schema, committed, as the API shows it."""
    row = station.create(session=session, kind=kind, spec=spec, created_by=key.name)
    warnings = kind.warnings(session, row) if kind.warnings else None
    session.commit()
    more = {} if warnings is None else {"warnings": warnings}
    return item_read(kind, row, spec.aircraft, **more)


def _add_kind(kind: Kind) -> None:
    """The six routes of one kind of item."""
    base, noun, plural = f"/{kind.path}", kind.noun.lower(), kind.noun.lower() + "s"
    item = base + "/{item_id}"
    status_filter = Annotated[str | None, Query(
        pattern="^(" + "|".join(kind.statuses) + ")$")]

    def create_item(body: Any, session: SessionDep, key: Operator) -> BaseModel:
        return _create(kind, body, session, key)

    def list_items(session: SessionDep, _: Reader, aircraft: str | None = None,
              status: str | None = None,
              limit: Annotated[int, Query(ge=1, le=500)] = 100,
              offset: Offset = 0) -> Page[Any]:
        rows, total = station.list_(session=session, kind=kind, tail=aircraft, status=status,
                                    limit=limit, offset=offset)
        return Page(items=[item_read(kind, r, t) for r, t in rows], total=total, limit=limit,
                    offset=offset)

    def get_item(item_id: IdPath, session: SessionDep, _: Reader) -> BaseModel:
        row = station.get(session=session, kind=kind, item_id=item_id)
        return item_read(kind, row, _tail(session, row))

    def cancel_item(item_id: IdPath, session: SessionDep, _: Operator) -> BaseModel:
        row = station.cancel(session=session, kind=kind, item_id=item_id)
        session.commit()
        return item_read(kind, row, _tail(session, row))

    def report_truth(item_id: IdPath, body: Any, session: SessionDep, _: Operator
               ) -> BaseModel:
        row = station.report_truth(session=session, kind=kind, item_id=item_id, body=body)
        session.commit()
        return truth_read(kind, row)

    def list_truth(item_id: IdPath, session: SessionDep, _: Reader) -> list[BaseModel]:
        return [truth_read(kind, r) for r in station.list_truth(session=session, kind=kind,
                                                                 item_id=item_id)]

    router.post(base, status_code=201, response_model=kind.read, responses=errors(404, 409),
                summary=f"Create a {noun} (operator)")(
        _typed(create_item, body=kind.spec))
    router.get(base, response_model=Page[kind.read],  # type: ignore[name-defined]
               summary=f"List {plural}")(
        _typed(list_items, status=status_filter))
    router.get(item, response_model=kind.read, summary=f"One {noun}")(get_item)
    router.post(item + "/cancel", response_model=kind.read, responses=errors(409),
                summary=f"Cancel a pending or active {noun} (operator)")(cancel_item)
    router.put(item + "/ground-truth", response_model=kind.truth_read,
               summary=f"Sim worker: the {noun}'s truth on one flight (operator; idempotent; "
               "the first makes it active)")(
        _typed(report_truth, body=kind.truth_in))
    router.get(item + "/ground-truth", response_model=list[kind.truth_read],  # type: ignore[name-defined]
               summary=f"Truth of a {noun}, flight by flight")(list_truth)


# ---- one create for every kind: a body tagged with its kind --------------------------------

#: the union's discriminator. Not ``kind``: a sensor injection's and a condition's ``kind``
#: already says what it does (noise, load_scale, ...); its values are the kinds' keys, the
#: names the flight plan and the flight's report give them
DISCRIMINATOR = "station_kind"
_KEYED = {kind.key: kind for kind in KINDS}


def _tagged(model: type[BaseModel], kind: Kind, name: str) -> type[BaseModel]:
    """``model`` with the discriminator, a ``Literal`` of the kind's key (required)."""
    tag = Literal[kind.key]  # type: ignore[name-defined]  # a value known at run time
    return create_model(  # type: ignore[call-overload]
        name, __base__=model, __doc__=f"{kind.noun}: {model.__name__} tagged with its kind.",
        **{DISCRIMINATOR: (tag, Field(description=f"'{kind.key}': a {kind.noun.lower()}"))})


#: per kind key, its create schema and its read model, each tagged
TAGGED_SPECS = {kind.key: _tagged(kind.spec, kind, f"Station{kind.spec.__name__}")
                for kind in KINDS}
TAGGED_READS = {kind.key: _tagged(kind.read, kind, f"Station{kind.read.__name__}")
                for kind in KINDS}


def _one_of(models: dict[str, type[BaseModel]]) -> Any:
    """The models as a union the discriminator picks from (OpenAPI ``oneOf`` + mapping)."""
    return Annotated[Union[tuple(models.values())],  # noqa: UP007  # a run-time union
                     Field(discriminator=DISCRIMINATOR)]


StationItemCreate = _one_of(TAGGED_SPECS)
StationItemRead = _one_of(TAGGED_READS)


def create_any(body: Any, session: SessionDep, key: Operator) -> Any:
    kind = _KEYED[getattr(body, DISCRIMINATOR)]
    # the kind's own schema again, without the tag: what its own route takes (and stores)
    spec = kind.spec.model_validate(body.model_dump(exclude={DISCRIMINATOR}))
    read = _create(kind, spec, session, key)
    return TAGGED_READS[kind.key].model_validate({**read.model_dump(), DISCRIMINATOR: kind.key})


router.post("/items", status_code=201, response_model=StationItemRead,
            responses=errors(404, 409),
            summary="Create a test-station item of any kind, named by station_kind "
            "(operator; as its kind's own POST)")(
    _typed(create_any, body=StationItemCreate))


# ---- the simulator's flight: its plan and its report ---------------------------------------

#: what is on an aircraft for one flight: the aircraft (its installed units) and, per kind,
#: the items to fly (``GET /test-station/plan``)
FlightPlan: type[BaseModel] = create_model(  # type: ignore[call-overload]
    "FlightPlan", aircraft=(AircraftRead, ...), flight=(int, ...),
    **{kind.key: (list[kind.read], Field(description=f"{kind.noun}s on the flight"))  # type: ignore[name-defined]
       for kind in KINDS})

#: what one flight flew: per kind, each planned item's truth on it (``PUT .../flights/{flight}``)
class _Report(BaseModel):
    model_config = ConfigDict(extra="forbid")


FlightReport: type[BaseModel] = create_model(  # type: ignore[call-overload]
    "FlightReport", __base__=_Report, aircraft=(Identifier, ...),
    flight_number=(FlightNumber, ...),
    **{kind.key: (list[kind.flown], Field(default_factory=list))  # type: ignore[name-defined]
       for kind in KINDS})


class FlightRecorded(BaseModel):
    aircraft: str
    flight: str
    recorded: dict[str, int] = Field(description="truths recorded per kind")


@router.get("/plan", response_model=FlightPlan, responses=errors(404),
            summary="Sim worker: what to fly on an aircraft's flight")
def plan(aircraft: Annotated[str, Query(pattern=ID_PATTERN, max_length=MAX_ID_LEN)],
         flight: Annotated[int, Query(ge=0, le=MAX_INT32)], session: SessionDep, _: Reader
         ) -> BaseModel:
    row, live = station.flight_plan(session=session, tail=aircraft, flight=flight)
    return FlightPlan.model_validate({
        "aircraft": aircraft_read(row), "flight": flight,
        **{kind.key: [item_read(kind, r, aircraft) for r in live[kind.key]] for kind in KINDS}})


def report_flight(flight: FlightPath, body: Any, session: SessionDep, _: Operator
            ) -> FlightRecorded:
    recorded = station.report_flight(
        session=session, tail=body.aircraft, flight_code=flight,
        flight_number=body.flight_number, flown={k.key: getattr(body, k.key) for k in KINDS})
    session.commit()
    return FlightRecorded(aircraft=body.aircraft, flight=flight, recorded=recorded)


router.put("/flights/{flight}", response_model=FlightRecorded, responses=errors(404, 409),
           summary="Sim worker: what one flight flew, every item's truth at once (operator; "
           "idempotent)")(_typed(report_flight, body=FlightReport))


# ---- kept for clients of the per-injection status ------------------------------------------

@router.post("/injections/{item_id}/status", response_model=InjectionRead,
             responses=errors(409), deprecated=True,
             summary="Sim worker: the fault started or reached failure (operator). Deprecated: "
             "PUT /test-station/flights/{flight} reports both with the flight's truth")
def set_status(item_id: IdPath, body: InjectionStatus, session: SessionDep, _: Operator
               ) -> BaseModel:
    row = station.get(session=session, kind=FAULTS, item_id=item_id)
    station_faults.set_status(session=session, row=row, status=body.status,
                              failure_flight=body.failure_flight,
                              planned_failure_flight=body.planned_failure_flight)
    session.commit()
    return item_read(FAULTS, row, _tail(session, row))


for _kind in KINDS:
    _add_kind(_kind)

__all__ = ["router", "item_read", "truth_read", "FlightPlan", "FlightReport", "DISCRIMINATOR",
           "StationItemCreate", "StationItemRead"]
