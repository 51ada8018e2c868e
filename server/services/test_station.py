"""Test station: fault injections into simulated aircraft, and the ground truth reported back.

An injection is ``pending`` until the sim worker simulates its onset flight, then ``active``;
``cancelled`` by an operator, or ``failed`` once the actuator reaches the failure threshold.
One pending/active injection per actuator at a time (one fault at a time, as in the paper).
A reported failure makes the installed actuator at the position ``failed`` (a state, until it
is replaced); replacing the actuator ends its injection (:func:`end_injections_at`): the new
unit is healthy.
"""

from __future__ import annotations

from sqlalchemy import select
from sqlalchemy.orm import Session

from server.errors import Conflict, NotFound, Unprocessable
from server.models import Actuator, Aircraft, GroundTruth, Injection, utcnow
from server.services.station_items import add_live, cancel_live, page_with_tail
from server.vocabulary import FAULT_MODES, PROGRESSIVE, STATION_LIVE

__all__ = ["PROGRESSIVE", "create_injection", "span_warning", "list_injections", "get_injection",
           "cancel_injection", "update_injection_status", "report_ground_truth",
           "list_ground_truth", "end_injections_at"]



def create_injection(*, session: Session, tail: str, position: str, fault_mode: str,
                     onset_flight: int, time_to_failure_flights: int | None,
                     severity: float | None, created_by: str) -> Injection:
    aircraft = session.scalar(select(Aircraft).where(Aircraft.tail == tail))
    if aircraft is None:
        raise NotFound(f"Aircraft '{tail}' does not exist.")
    if fault_mode not in FAULT_MODES:
        raise Unprocessable(f"Unknown fault mode '{fault_mode}'.", code="unknown_fault_mode")
    if fault_mode == "REWEAR" and position == "WT":
        raise Unprocessable("Rod-end wear (REWEAR) is monitored on the winglet pair only: "
                            "use WL1 or WL2.", code="invalid_position")
    if fault_mode not in PROGRESSIVE and time_to_failure_flights is not None:
        raise Unprocessable(f"{fault_mode} is imposed a priori; it has no time to failure.",
                            code="not_progressive")
    live = session.scalar(select(Injection).where(
        Injection.aircraft_id == aircraft.id, Injection.status.in_(STATION_LIVE)))
    if live is not None:
        raise Conflict(f"Aircraft '{tail}' already has a live injection ({live.fault_mode} on "
                       f"{live.position}); the simulator runs one fault at a time.",
                       code="injection_exists", details={"injection_id": live.id})
    row = Injection(aircraft_id=aircraft.id, position=position, fault_mode=fault_mode,
                    onset_flight=onset_flight, time_to_failure_flights=time_to_failure_flights,
                    severity=severity, created_by=created_by, status="pending")
    return add_live(session, row, lambda: Conflict(
        f"Aircraft '{tail}' was given a live injection concurrently; the simulator runs one "
        "fault at a time.", code="injection_exists"))


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


def get_injection(*, session: Session, injection_id: int) -> Injection:
    row = session.get(Injection, injection_id)
    if row is None:
        raise NotFound(f"Injection {injection_id} does not exist.")
    return row


def list_injections(*, session: Session, tail: str | None, status: str | None, limit: int,
                    offset: int) -> tuple[list[tuple[Injection, str]], int]:
    return page_with_tail(session=session, model=Injection, tail=tail, status=status,
                          limit=limit, offset=offset)


def cancel_injection(*, session: Session, injection_id: int) -> Injection:
    return cancel_live(get_injection(session=session, injection_id=injection_id),
                       f"Injection {injection_id}")


def update_injection_status(*, session: Session, injection_id: int, status: str,
                            failure_flight: int | None = None,
                            planned_failure_flight: int | None = None) -> Injection:
    """Sim worker: pending -> active at onset (with the flight a progressive fault is planned
    to fail at), active -> failed at the threshold."""
    row = get_injection(session=session, injection_id=injection_id)
    if planned_failure_flight is not None and row.status in STATION_LIVE:
        row.planned_failure_flight = planned_failure_flight
    allowed = {"pending": {"active", "failed"}, "active": {"failed"}}
    if status == row.status:
        return row
    if status not in allowed.get(row.status, set()):
        raise Conflict(f"Injection {injection_id} cannot go from {row.status} to {status}.",
                       code="bad_transition")
    row.status = status
    if failure_flight is not None:
        row.failure_flight = failure_flight
    if status == "failed":
        unit = session.scalar(select(Actuator).where(
            Actuator.aircraft_id == row.aircraft_id, Actuator.position == row.position,
            Actuator.removed_at.is_(None)))
        if unit is not None and unit.failed_at_flight is None:
            unit.failed_at_flight = row.failure_flight if row.failure_flight is not None else 0
            unit.failed_at = utcnow()
    return row


def end_injections_at(*, session: Session, aircraft_id: int, position: str) -> list[Injection]:
    """The actuator at ``position`` was replaced: its pending or active injection is cancelled
    (the new unit carries no fault); a failed one stays failed, with ``cancelled_at`` marking
    that its unit is gone."""
    rows = list(session.scalars(select(Injection).where(
        Injection.aircraft_id == aircraft_id, Injection.position == position,
        Injection.status.in_((*STATION_LIVE, "failed")), Injection.cancelled_at.is_(None))))
    now = utcnow()
    for row in rows:
        if row.status in STATION_LIVE:
            row.status = "cancelled"
        row.cancelled_at = now
    return rows


def report_ground_truth(*, session: Session, injection_id: int, flight_code: str,
                        flight_number: int, severity: float, severity_norm: float,
                        true_rul_flights: int | None) -> GroundTruth:
    """Record (idempotently) the true fault state of one simulated flight."""
    get_injection(session=session, injection_id=injection_id)
    row = session.scalar(select(GroundTruth).where(GroundTruth.injection_id == injection_id,
                                                   GroundTruth.flight_code == flight_code))
    if row is None:
        row = GroundTruth(injection_id=injection_id, flight_code=flight_code)
        session.add(row)
    row.flight_number = flight_number
    row.severity = severity
    row.severity_norm = severity_norm
    row.true_rul_flights = true_rul_flights
    session.flush()
    return row


def list_ground_truth(*, session: Session, injection_id: int) -> list[GroundTruth]:
    get_injection(session=session, injection_id=injection_id)  # 404 for an unknown one
    return list(session.scalars(select(GroundTruth).where(
        GroundTruth.injection_id == injection_id).order_by(GroundTruth.flight_number)))
