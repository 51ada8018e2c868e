"""The test station: what an operator schedules on a simulated aircraft from a flight on, what
the simulator flies of it, and the truth it reports back.

Every kind of item (fault injections, sensor injections, conditions) is one :class:`Kind` of
:data:`KINDS`: its tables, its schemas and the few rules of its own. One set of operations
serves them all (create, list, get, cancel, report truth, list truth), as do the API's routes
(``server/api/test_station.py``), the station page's forms and the simulator's flight plan
(:func:`flight_plan`, :func:`report_flight`).

An item is ``pending`` until the simulator first flies it (its first truth makes it
``active``), then lasts until an operator cancels it; a fault injection also ends ``failed``
when its actuator reaches the failure threshold (:mod:`server.services.station_faults`). One
live item per slot (the kind's ``slot`` columns, held by the database's partial unique index).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

from pydantic import BaseModel
from sqlalchemy import ColumnElement, and_, false, func, or_, select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from server.errors import Conflict, NotFound, Unprocessable
from server.models import (
    Aircraft,
    ConditionGroundTruth,
    GroundTruth,
    Injection,
    SensorGroundTruth,
    SensorInjection,
    SimCondition,
    utcnow,
)
from server.schemas import (
    AppliedFlown,
    AppliedTruthIn,
    ConditionCreate,
    ConditionRead,
    ConditionTruthRead,
    FaultFlown,
    GroundTruthIn,
    GroundTruthRead,
    InjectionCreate,
    InjectionRead,
    SensorInjectionCreate,
    SensorInjectionRead,
    SensorTruthRead,
)
from server.services import station_faults
from server.vocabulary import SENSOR_OF_SIGNAL, STATION_LIVE, StationStatus

__all__ = ["Kind", "KINDS", "FAULTS", "SENSORS", "CONDITIONS", "kind_named", "create", "get",
           "list_", "cancel", "add_live", "report_truth", "list_truth", "end_at", "flights_under",
           "describe_condition", "flight_plan", "report_flight"]

Row = Any  # a mapped item class of a kind (aircraft_id, status, onset_flight, ...)


@dataclass(frozen=True)
class Kind:
    """One kind of test-station item: where it is stored, what the API takes and gives, and
    the rules it does not share."""

    #: the API's and the page's path segment (``/test-station/<path>``)
    path: str
    #: its key in the flight plan and the flight's truth report (a Python name)
    key: str
    #: the station page's form (its id prefix; the page names the form that failed)
    form: str
    #: "Injection", "Sensor injection": the start of the kind's messages
    noun: str
    row: type
    truth: type
    #: the column of ``truth`` naming the item (also the key of its truth-read)
    truth_key: str
    #: the columns besides ``aircraft_id`` that hold one live item at a time
    slot: tuple[str, ...]
    #: the states its items take (the list's filter)
    statuses: tuple[StationStatus, ...]
    spec: type[BaseModel]
    read: type[BaseModel]
    truth_in: type[BaseModel]
    truth_read: type[BaseModel]
    #: one item's truth in the flight's report (its id and the truth's values)
    flown: type[BaseModel]
    #: the 409 when the slot is taken: (tail, spec, the live item) -> Conflict
    taken: Callable[[str, Any, Any], Conflict]
    #: the 409 when a concurrent request took the slot first: (tail, spec) -> Conflict
    raced: Callable[[str, Any], Conflict]
    #: refuses (422) what the schema cannot tell alone
    check: Callable[[Any], None] = lambda spec: None
    #: fields of its read model computed from the row (beyond the row's columns)
    derived: Callable[[Any], dict[str, Any]] = lambda row: {}
    #: what an operator should know of a new item (the read's ``warnings``)
    warnings: Callable[[Session, Any], list[str]] | None = None
    #: the kind's own effect of a flight's report on the item, after its truth is recorded
    on_flown: Callable[[Session, Any, Any], None] = lambda session, item, flown: None
    #: items that are no longer live but were on the aircraft on flight ``n`` (SQL)
    still_on: Callable[[int], ColumnElement[bool]] = field(default=lambda n: false())
    #: whether it sits on an actuator (replacing the unit ends it)
    on_unit: bool = True

    @property
    def truth_fields(self) -> tuple[str, ...]:
        """The values a truth row holds beyond its flight."""
        return tuple(f for f in self.truth_in.model_fields if f not in ("flight",
                                                                          "flight_number"))

    def what(self, item_id: int) -> str:
        return f"{self.noun} {item_id}"


def _channels(row: SensorInjection) -> dict[str, Any]:
    return {"channels": [f"{row.position}.{s}" for s, of in SENSOR_OF_SIGNAL.items()
                         if of == row.sensor]}


def describe_condition(row: SimCondition) -> str:
    """The condition in a few words, e.g. ``load_scale 1.5`` or ``base Abu Dhabi``."""
    return f"{row.kind} {row.base if row.kind == 'base' else format(row.value, 'g')}"


#: the states of the kinds that have no failure
_NEVER_FAILS = (StationStatus.PENDING, StationStatus.ACTIVE, StationStatus.CANCELLED)

FAULTS = Kind(
    path="injections", key="injections", form="fault", noun="Injection", row=Injection,
    truth=GroundTruth, truth_key="injection_id", slot=("position", "fault_mode"),
    statuses=tuple(StationStatus), spec=InjectionCreate, read=InjectionRead,
    truth_in=GroundTruthIn, truth_read=GroundTruthRead, flown=FaultFlown,
    # faults fly concurrently, on other actuators or of other modes on one; a mode has one
    # severity per actuator, so a second of the same mode there has no meaning
    taken=lambda tail, spec, live: Conflict(
        f"{tail} {spec.position} already has a live {spec.fault_mode} injection (injection "
        f"{live.id}); an actuator carries one fault per mode: cancel it first.",
        code="injection_exists", details={"injection_id": live.id}),
    raced=lambda tail, spec: Conflict(
        f"{tail} {spec.position} was given a live {spec.fault_mode} injection concurrently; "
        "an actuator carries one fault per mode.", code="injection_exists"),
    check=station_faults.check, warnings=station_faults.create_warnings,
    on_flown=station_faults.on_flown, still_on=station_faults.failed_after)

SENSORS = Kind(
    path="sensor-injections", key="sensor_injections", form="sensor", noun="Sensor injection",
    row=SensorInjection, truth=SensorGroundTruth, truth_key="sensor_injection_id",
    slot=("position", "sensor"), statuses=_NEVER_FAILS,
    spec=SensorInjectionCreate, read=SensorInjectionRead, truth_in=AppliedTruthIn,
    truth_read=SensorTruthRead, flown=AppliedFlown,
    # two transforms of one sensor would compose in an order the operator did not choose
    taken=lambda tail, spec, live: Conflict(
        f"The {spec.sensor} of {tail} {spec.position} already has a live sensor injection "
        f"({live.kind}); cancel it first.", code="sensor_injection_exists",
        details={"sensor_injection_id": live.id}),
    raced=lambda tail, spec: Conflict(
        f"The {spec.sensor} of {tail} {spec.position} was given a live sensor injection "
        "concurrently; cancel it first.", code="sensor_injection_exists"),
    derived=_channels)

CONDITIONS = Kind(
    path="conditions", key="conditions", form="condition", noun="Condition", row=SimCondition,
    truth=ConditionGroundTruth, truth_key="condition_id", slot=("kind",),
    statuses=_NEVER_FAILS, spec=ConditionCreate, read=ConditionRead,
    truth_in=AppliedTruthIn, truth_read=ConditionTruthRead, flown=AppliedFlown,
    # of different kinds they compose (hotter air and larger loads on the same flights)
    taken=lambda tail, spec, live: Conflict(
        f"{tail} already has a live {spec.kind} condition ({describe_condition(live)}); "
        "cancel it first.", code="condition_exists", details={"condition_id": live.id}),
    raced=lambda tail, spec: Conflict(
        f"{tail} was given a live {spec.kind} condition concurrently; cancel it first.",
        code="condition_exists"),
    on_unit=False)  # it belongs to the aircraft: replacing a unit leaves it live

#: the registry: every kind of test-station item, in the order the page and the plan show them
KINDS: tuple[Kind, ...] = (FAULTS, SENSORS, CONDITIONS)


def kind_named(path: str) -> Kind:
    for kind in KINDS:
        if kind.path == path:
            return kind
    raise NotFound(f"The test station has no '{path}'.")


def _aircraft(session: Session, tail: str) -> Aircraft:
    aircraft = session.scalar(select(Aircraft).where(Aircraft.tail == tail))
    if aircraft is None:
        raise NotFound(f"Aircraft '{tail}' does not exist.")
    return aircraft


def _live(row: Row) -> ColumnElement[bool]:
    return row.status.in_(STATION_LIVE)


def create(*, session: Session, kind: Kind, spec: Any, created_by: str) -> Any:
    """A new pending item of ``kind`` from its ``spec`` (the kind's create schema); 409 while
    its slot holds a live one."""
    aircraft = _aircraft(session, spec.aircraft)
    kind.check(spec)
    row: Row = kind.row
    live = session.scalar(select(row).where(
        row.aircraft_id == aircraft.id, _live(row),
        *(getattr(row, c) == getattr(spec, c) for c in kind.slot)))
    if live is not None:
        raise kind.taken(spec.aircraft, spec, live)
    return add_live(session, kind, row(
        aircraft_id=aircraft.id, created_by=created_by, status=StationStatus.PENDING,
        **spec.model_dump(exclude={"aircraft"})), spec)


def add_live(session: Session, kind: Kind, item: Any, spec: Any) -> Any:
    """``item`` (a new live item, made from ``spec``) added and flushed; the kind's ``raced``
    409 if a concurrent request made a live item in the same slot first (the database's
    partial unique index holds where the check before the insert cannot)."""
    session.add(item)
    try:
        session.flush()
    except IntegrityError:
        raise kind.raced(spec.aircraft, spec) from None
    return item


def get(*, session: Session, kind: Kind, item_id: int) -> Any:
    item = session.get(kind.row, item_id)
    if item is None:
        raise NotFound(f"{kind.what(item_id)} does not exist.")
    return item


def list_(*, session: Session, kind: Kind, tail: str | None, status: str | None, limit: int,
          offset: int) -> tuple[list[tuple[Any, str]], int]:
    """Items of ``kind`` (newest first) with their aircraft's tail, and how many there are,
    optionally of one aircraft and one status."""
    row: Row = kind.row
    query = select(row, Aircraft.tail).join(Aircraft)
    if tail:
        query = query.where(Aircraft.tail == tail)
    if status:
        query = query.where(row.status == status)
    total = session.scalar(select(func.count()).select_from(query.subquery())) or 0
    rows = session.execute(query.order_by(row.id.desc()).limit(limit).offset(offset)).all()
    return [(r[0], r[1]) for r in rows], total


def cancel(*, session: Session, kind: Kind, item_id: int) -> Any:
    """The item cancelled now; 409 ``not_live`` if it is not live."""
    item = get(session=session, kind=kind, item_id=item_id)
    if item.status not in STATION_LIVE:
        raise Conflict(f"{kind.what(item_id)} is {item.status}; only pending or active ones "
                       "can be cancelled.", code="not_live")
    item.status = StationStatus.CANCELLED
    item.cancelled_at = utcnow()
    return item


def _record(session: Session, kind: Kind, item: Any, flight_code: str, flight_number: int,
            values: dict[str, Any]) -> Any:
    """Record (idempotently) the item's truth on one flight; the first makes a pending item
    active from that flight."""
    if item.status == StationStatus.PENDING:
        item.status = StationStatus.ACTIVE
        if hasattr(item, "started_flight"):
            item.started_flight = flight_number
    truth: Row = kind.truth
    row = session.scalar(select(truth).where(getattr(truth, kind.truth_key) == item.id,
                                             truth.flight_code == flight_code))
    if row is None:
        row = truth(**{kind.truth_key: item.id, "flight_code": flight_code})
        session.add(row)
    row.flight_number = flight_number
    for name, value in values.items():
        setattr(row, name, value)
    session.flush()
    return row


def report_truth(*, session: Session, kind: Kind, item_id: int, body: Any) -> Any:
    """One flight's truth of one item (``body``: the kind's truth-in schema)."""
    item = get(session=session, kind=kind, item_id=item_id)
    return _record(session, kind, item, body.flight, body.flight_number,
                   body.model_dump(include=set(kind.truth_fields)))


def list_truth(*, session: Session, kind: Kind, item_id: int) -> list[Any]:
    """The item's truth, flight by flight."""
    get(session=session, kind=kind, item_id=item_id)  # 404 for an unknown one
    truth: Row = kind.truth
    return list(session.scalars(select(truth).where(getattr(truth, kind.truth_key) == item_id)
                                .order_by(truth.flight_number)))


def end_at(*, session: Session, aircraft_id: int, position: str) -> None:
    """The actuator at ``position`` was replaced: the items on it are over (the new unit is
    sound). A live one is cancelled; a failed one stays failed, with ``cancelled_at`` marking
    that its unit is gone."""
    now = utcnow()
    for kind in KINDS:
        if not kind.on_unit:
            continue
        row: Row = kind.row
        for item in session.scalars(select(row).where(
                row.aircraft_id == aircraft_id, row.position == position,
                row.status.in_((*STATION_LIVE, StationStatus.FAILED)),
                row.cancelled_at.is_(None))):
            if item.status in STATION_LIVE:
                item.status = StationStatus.CANCELLED
            item.cancelled_at = now


def flights_under(*, session: Session, kind: Kind, aircraft_id: int) -> dict[str, list[Any]]:
    """Flight code -> the items of ``kind`` it was flown under (their truth), oldest first."""
    row: Row = kind.row
    truth: Row = kind.truth
    rows = session.execute(select(truth, row).join(
        row, row.id == getattr(truth, kind.truth_key)).where(
        row.aircraft_id == aircraft_id).order_by(row.id, truth.flight_number)).all()
    out: dict[str, list[Any]] = {}
    for truth_row, item in rows:
        out.setdefault(truth_row.flight_code, []).append((item, truth_row))
    return out


# ---- the simulator's flight: one plan, one report ------------------------------------------

def flight_plan(*, session: Session, tail: str, flight: int) -> tuple[Aircraft, dict[str, list]]:
    """The aircraft and, per kind (its key), the items on it for flight ``flight``, oldest
    first: the active ones, the pending ones whose onset has come, and those a kind keeps on
    the aircraft after they end (a failed fault stays on its unit)."""
    aircraft = _aircraft(session, tail)
    live: dict[str, list] = {}
    for kind in KINDS:
        row: Row = kind.row
        on_flight = or_(row.status == StationStatus.ACTIVE,
                        and_(row.status == StationStatus.PENDING, row.onset_flight <= flight),
                        kind.still_on(flight))
        live[kind.key] = list(session.scalars(select(row).where(
            row.aircraft_id == aircraft.id, on_flight).order_by(row.id)))
    return aircraft, live


def report_flight(*, session: Session, tail: str, flight_code: str, flight_number: int,
                  flown: dict[str, Sequence[Any]]) -> dict[str, int]:
    """What one flight flew, every kind at once (``flown``: kind key -> the kind's flown
    items); idempotent. Returns how many truths of each kind were recorded."""
    aircraft = _aircraft(session, tail)
    recorded = {}
    for kind in KINDS:
        items = flown.get(kind.key) or ()
        for entry in items:
            item = get(session=session, kind=kind, item_id=entry.id)
            if item.aircraft_id != aircraft.id:
                raise Unprocessable(f"{kind.what(entry.id)} is not on {tail}.",
                                    code="not_on_aircraft")
            _record(session, kind, item, flight_code, flight_number,
                    entry.model_dump(include=set(kind.truth_fields)))
            kind.on_flown(session, item, entry)
        recorded[kind.key] = len(items)
    session.flush()
    return recorded
