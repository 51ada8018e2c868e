"""What a fault injection has of its own among the test station's kinds (server/services/
station.py): its mode's rules, the warning on a time to failure the model has not seen, the
planned failure flight, and the failure itself.

Faults fly concurrently: one live injection per mode of each actuator (its slot), so an
aircraft may carry faults on several actuators and several modes on one. A reported failure
makes the installed actuator at the position ``failed`` (a state, until it is replaced) and
gives every flight the injection was reported on its true RUL (only known in hindsight); the
failure ends that injection only. Replacing the actuator ends every injection on it
(``station.end_at``): a second fault on the failed unit is cancelled with its RUL unknown
(censored), and the new unit is healthy; injections on other actuators fly on.
"""

from __future__ import annotations

from typing import Any

from sqlalchemy import ColumnElement, and_, case, select, update
from sqlalchemy.orm import Session

from server.errors import Conflict, Unprocessable
from server.models import Actuator, GroundTruth, Injection, utcnow
from server.vocabulary import PROGRESSIVE, STATION_LIVE, StationStatus

__all__ = ["check", "span_warning", "create_warnings", "on_flown", "failed_after",
           "set_status"]


def check(spec: Any) -> None:
    """Refuse (422) what the schema cannot tell alone."""
    if spec.fault_mode == "REWEAR" and spec.position == "WT":
        raise Unprocessable("Rod-end wear (REWEAR) is monitored on the winglet pair only: "
                            "use WL1 or WL2.", code="invalid_position")
    if spec.fault_mode not in PROGRESSIVE and spec.time_to_failure_flights is not None:
        raise Unprocessable(f"{spec.fault_mode} is imposed a priori; it has no time to "
                            "failure.", code="not_progressive")


def span_warning(*, session: Session, fault_mode: str,
                 time_to_failure_flights: int | None) -> str | None:
    """A warning when the requested time to failure lies outside the spans the active model's
    prognosis was trained on (its RUL for such a fault is an extrapolation); None otherwise."""
    if time_to_failure_flights is None:
        return None
    from server.services.models import active_version

    version = active_version(session=session)
    spans = ((version.training or {}).get("campaign") or {}).get("spans_flights") or {} \
        if version is not None else {}
    span = spans.get(fault_mode)
    if not span or span[0] <= time_to_failure_flights <= span[1]:
        return None
    return (f"The active model was trained on {fault_mode} faults that took {span[0]}-{span[1]} "
            f"flights from onset to failure; its RUL for a {time_to_failure_flights}-flight "
            "fault is an extrapolation and may be far off.")


def create_warnings(session: Session, row: Injection) -> list[str]:
    warning = span_warning(session=session, fault_mode=row.fault_mode,
                           time_to_failure_flights=row.time_to_failure_flights)
    return [warning] if warning else []


def failed_after(flight: int) -> ColumnElement[bool]:
    """A failed injection is still on its unit on the flights before its failure flight (the
    simulator may fly the last of them again after a restart)."""
    return and_(Injection.status == StationStatus.FAILED, Injection.failure_flight > flight)


def on_flown(session: Session, row: Injection, flown: Any) -> None:
    """A flight's report: the flight the fault is steered to fail at, and its failure."""
    if flown.planned_failure_flight is not None and row.status in STATION_LIVE:
        row.planned_failure_flight = flown.planned_failure_flight
    if flown.failure_flight is not None:
        _fail(session, row, flown.failure_flight)


def set_status(*, session: Session, row: Injection, status: str,
               failure_flight: int | None = None,
               planned_failure_flight: int | None = None) -> Injection:
    """pending -> active at onset (with the flight a progressive fault is planned to fail
    at), pending or active -> failed at the threshold (``POST .../status``, which the flight's
    report replaces)."""
    if planned_failure_flight is not None and row.status in STATION_LIVE:
        row.planned_failure_flight = planned_failure_flight
    if status == row.status:
        return row
    if status == StationStatus.FAILED:
        _fail(session, row, failure_flight)
    elif status == StationStatus.ACTIVE and row.status == StationStatus.PENDING:
        row.status = StationStatus.ACTIVE
        if failure_flight is not None:
            row.failure_flight = failure_flight
    else:
        raise Conflict(f"Injection {row.id} cannot go from {row.status} to {status}.",
                       code="bad_transition")
    return row


def _fail(session: Session, row: Injection, failure_flight: int | None) -> None:
    """The fault reached its threshold: the injection failed, its installed unit failed, and
    every flight reported gets its true RUL in one statement."""
    if row.status == StationStatus.FAILED:
        return
    if row.status not in STATION_LIVE:
        raise Conflict(f"Injection {row.id} cannot go from {row.status} to failed.",
                       code="bad_transition")
    row.status = StationStatus.FAILED
    if failure_flight is not None:
        row.failure_flight = failure_flight
    unit = session.scalar(select(Actuator).where(
        Actuator.aircraft_id == row.aircraft_id, Actuator.position == row.position,
        Actuator.removed_at.is_(None)))
    if unit is not None and unit.failed_at_flight is None:
        unit.failed_at_flight = row.failure_flight if row.failure_flight is not None else 0
        unit.failed_at = utcnow()
    if row.failure_flight is not None:
        session.flush()
        left = row.failure_flight - GroundTruth.flight_number
        session.execute(update(GroundTruth).where(GroundTruth.injection_id == row.id).values(
            true_rul_flights=case((left > 0, left), else_=0)))
