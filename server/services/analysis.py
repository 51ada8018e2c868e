"""Per-flight analysis results: which flight to analyse, the actuators and their stored
states, the chain run over them, and everything it says stored (health records, states,
alarms, prognoses). The ``analyze_flight`` job (:mod:`server.jobs.pipeline`) is wiring around
these; like every service they flush and leave the unit of work to the caller.

A job that runs twice (a worker died after committing, before marking the job done) finds the
flight's health records and writes nothing again.
"""

from __future__ import annotations

import logging
import math
from contextlib import nullcontext
from dataclasses import dataclass
from typing import Any

import numpy as np
from sqlalchemy import select
from sqlalchemy.orm import Session

from server.errors import Conflict, NotFound
from server.models import (
    Actuator,
    ActuatorState,
    Aircraft,
    Alarm,
    AlarmEvent,
    Flight,
    HealthRecord,
    Job,
    JobKind,
    Prognosis,
    utcnow,
)
from server.phm.chain import ActuatorHealth, ActuatorOutcome, PhmModel, analyze_flight
from server.phm.classification.modes import named_by_feature
from server.phm.features import FlightFeatures
from server.phm.prognosis import RulDistribution
from server.services.urgency import RUL_LOW_QUANTILE
from server.timing import StageClock
from server.vocabulary import AlarmStatus, FlightStatus, JobStatus

__all__ = ["FlightToAnalyse", "flight_to_analyse", "mark_analyzing", "mark_waiting",
           "mark_retrying", "reject", "mark_failed",
           "retry_failed", "failed_flights", "store_analysis", "json_safe"]

log = logging.getLogger("hmsm.analysis")


#: flight states after which there is nothing left to analyse (``failed``: until a retry)
_FINISHED = (FlightStatus.ANALYZED, FlightStatus.REJECTED, FlightStatus.FAILED)
_ERROR_CHARS = 500


@dataclass(frozen=True)
class FlightToAnalyse:
    """What the job needs of a stored flight to decode it."""

    flight_id: int
    aircraft_id: int | None
    blob_path: str
    sha256: str
    content_kind: str
    metadata: dict[str, Any]


def flight_to_analyse(*, session: Session, flight_id: int) -> FlightToAnalyse | None:
    """The flight's stored file and metadata; None if it is gone or already finished."""
    flight = session.get(Flight, flight_id)
    if flight is None or flight.status in _FINISHED:
        return None
    return FlightToAnalyse(flight.id, flight.aircraft_id, flight.blob_path, flight.sha256,
                           flight.content_kind, dict(flight.flight_metadata))


def mark_analyzing(*, session: Session, flight_id: int) -> None:
    """The analysis has started (a waiting flight's reason, :func:`mark_waiting`, is past)."""
    flight = session.get(Flight, flight_id)
    if flight is not None:
        flight.status, flight.reasons, flight.updated_at = FlightStatus.ANALYZING, [], utcnow()
        session.flush()


def mark_waiting(*, session: Session, flight_id: int, code: str, message: str) -> None:
    """The analysis stopped for a cause outside the flight (its log's store does not answer)
    and its job is queued again: the flight says ``queued`` too, with the cause as its reason,
    not ``analyzing`` while nothing runs."""
    flight = session.get(Flight, flight_id)
    if flight is not None and flight.status == FlightStatus.ANALYZING:
        flight.status, flight.updated_at = FlightStatus.QUEUED, utcnow()
        flight.reasons = [{"code": code, "message": message}]
        session.flush()


def mark_retrying(*, session: Session, flight_id: int, error: str, attempt: int,
                  of: int) -> None:
    """Attempt ``attempt`` of ``of`` failed and the job is queued again after a backoff: the
    flight says ``queued``, with the failure as its reason, until the next attempt starts."""
    mark_waiting(session=session, flight_id=flight_id, code="analysis_retried",
                 message=f"Attempt {attempt} of {of} failed ({_last_line(error)}); the "
                         "analysis is tried again.")


def reject(*, session: Session, flight_id: int, reasons: list[dict[str, Any]]) -> None:
    """The flight cannot be analysed: stored as rejected with machine-readable reasons."""
    flight = session.get(Flight, flight_id)
    if flight is not None:
        flight.status, flight.reasons, flight.updated_at = FlightStatus.REJECTED, reasons, utcnow()
        session.flush()


def mark_failed(*, session: Session, flight_id: int, error: str, attempts: int) -> None:
    """The analysis was given up (its job is dead): the flight is ``failed`` with the last
    error's final line, never ``analyzing`` for good, until an admin retries it."""
    flight = session.get(Flight, flight_id)
    if flight is None or flight.status in (FlightStatus.ANALYZED, FlightStatus.REJECTED):
        return
    flight.status, flight.updated_at = FlightStatus.FAILED, utcnow()
    flight.reasons = [{
        "code": "analysis_failed",
        "message": f"The analysis failed {attempts} time(s) and was given up; an admin can "
                   f"retry it (POST /api/v1/flights/{flight_id}/retry).",
        "details": {"attempts": attempts, "error": _last_line(error)}}]
    session.flush()


def _last_line(error: str) -> str:
    """The exception line of a traceback (its last), cut to a bounded length."""
    lines = error.strip().splitlines() or [""]
    line = lines[-1]
    return line if len(line) <= _ERROR_CHARS else line[:_ERROR_CHARS - 3] + "..."


def retry_failed(*, session: Session, flight_id: int) -> Flight:
    """Queue the analysis of a ``failed`` flight again, with a fresh count of attempts (its
    job row is reused: one analysis job per flight). Conflict unless the flight is failed."""
    flight = session.get(Flight, flight_id)
    if flight is None:
        raise NotFound(f"Flight {flight_id} does not exist.")
    if flight.status != FlightStatus.FAILED:
        raise Conflict(f"Flight {flight_id} is {flight.status}, not failed: there is nothing to "
                       "retry.", code="not_failed", details={"status": flight.status})
    job = session.scalar(select(Job).where(Job.kind == JobKind.ANALYZE_FLIGHT,
                                           Job.flight_id == flight_id))
    if job is None:
        job = Job(kind=JobKind.ANALYZE_FLIGHT, flight_id=flight_id,
                  lock_key=f"aircraft:{flight.aircraft_id}")
        session.add(job)
    now = utcnow()
    job.status, job.attempts, job.run_after, job.updated_at = JobStatus.QUEUED, 0, now, now
    job.last_error = job.lease_until = job.locked_by = job.started_at = job.finished_at = None
    flight.status, flight.reasons, flight.updated_at = FlightStatus.QUEUED, [], now
    session.flush()
    return flight


def failed_flights(*, session: Session, limit: int) -> list[Flight]:
    """The most recently failed flights first (one query; the dashboard lists them)."""
    return list(session.scalars(select(Flight).where(Flight.status == FlightStatus.FAILED)
                                .order_by(Flight.updated_at.desc(), Flight.id.desc())
                                .limit(limit)))


def store_analysis(*, session: Session, flight_id: int, features: FlightFeatures,
                   model_id: int, model: PhmModel, clock: StageClock | None = None) -> None:
    """Run the chain on the flight's features for every installed actuator not yet analysed
    on this flight, from its stored state, store what it says and mark the flight analysed.
    With a ``clock``, the chain's time is split into detection, classification and prognosis
    (the chain times the last two itself); the database work around it is in none of them."""
    flight = session.get(Flight, flight_id)
    if flight is None:
        return
    todo = [a for a in _installed(session, flight.aircraft_id)
            if a.id not in _analysed_on(session, flight_id)]
    states = {a.id: session.get(ActuatorState, a.id) for a in todo}
    health = {a.position: _health_of(model, a, states[a.id]) for a in todo}
    aircraft = session.get(Aircraft, flight.aircraft_id)
    timed = nullcontext() if clock is None else clock.rest("detection")
    with timed:
        outcomes = analyze_flight(model, features, health, seed=flight_id,
                                  started_at=flight.started_at,  # aware (UTCDateTime)
                                  base=None if aircraft is None else aircraft.base,
                                  stage=None if clock is None else clock.stage)
    for act in todo:
        out = outcomes[act.position]
        quality = {ch: q for ch, q in features.quality.items()
                   if ch.startswith(f"{act.position}.")}
        _store_record(session, flight, act, out, model_id, quality)
        _store_state(session, flight, act, out, health[act.position], states[act.id])
        rul = _store_prognosis(session, flight, act, out)
        _store_alarm(session, flight, act, out, rul)
    flight.status, flight.updated_at = FlightStatus.ANALYZED, utcnow()
    session.flush()


def _installed(session: Session, aircraft_id: int | None) -> list[Actuator]:
    return list(session.scalars(select(Actuator).where(
        Actuator.aircraft_id == aircraft_id, Actuator.removed_at.is_(None))))


def _analysed_on(session: Session, flight_id: int) -> set[int]:
    return set(session.scalars(select(HealthRecord.actuator_id).where(
        HealthRecord.flight_id == flight_id)))


def _health_of(model: PhmModel, act: Actuator, state: ActuatorState | None) -> ActuatorHealth:
    if state is not None and state.detection:
        return ActuatorHealth.from_dict(state.detection)
    return model.new_health(act.position)


def json_safe(value: Any) -> Any:
    """JSON that every backend stores: non-finite floats (invalid features) become null."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [json_safe(v) for v in value]
    if isinstance(value, np.generic):
        return json_safe(value.item())
    return value


def _store_record(session: Session, flight: Flight, act: Actuator, out: ActuatorOutcome,
                  model_id: int, quality: dict[str, dict[str, float]]) -> None:
    """The flight's health record of one actuator, with its channels' signal quality."""
    session.add(HealthRecord(
        actuator_id=act.id, flight_id=flight.id, model_version_id=model_id,
        flight_index=out.flight_index, started_at=flight.started_at,
        features=json_safe(out.features),
        scores=json_safe({"z": out.z, "confidence": out.confidence,
                          "alarm_features": out.alarm_features,
                          "sensor_findings": out.sensor_findings,
                          "set_aside": out.set_aside, "widened": out.widened,
                          "outside_design": out.outside_design,
                          "quality": quality}),
        confidence=out.max_confidence, alarm=out.alarm,
        class_probabilities=json_safe(out.class_probabilities)))


def _store_state(session: Session, flight: Flight, act: Actuator, out: ActuatorOutcome,
                 health: ActuatorHealth, state: ActuatorState | None) -> None:
    doc = json_safe(health.to_dict())
    doc["confidence"] = out.max_confidence
    doc["sensor_findings"] = json_safe(out.sensor_findings)  # the latest flight's
    doc["outside_design"] = json_safe(out.outside_design)  # the latest flight's
    if state is None:
        state = ActuatorState(actuator_id=act.id)
        session.add(state)
    state.detection = doc
    state.flights_seen = out.flight_index
    state.last_flight_id = flight.id
    state.fault_mode = out.fault_mode
    state.updated_at = utcnow()


def _store_prognosis(session: Session, flight: Flight, act: Actuator, out: ActuatorOutcome
                     ) -> RulDistribution | None:
    """The unit's RUL (its earliest failure among the modes present), under its mode."""
    mode = out.rul_mode or out.fault_mode
    if out.rul is not None and mode is not None:
        session.add(Prognosis(actuator_id=act.id, flight_id=flight.id,
                              flight_index=out.flight_index, fault_mode=mode,
                              distribution=json_safe(out.rul.to_dict())))
    return out.rul


def _modes_present(out: ActuatorOutcome, confirmed: str | None) -> list[dict[str, Any]] | None:
    """The alarm's ``modes``: each mode present with its own probability, median RUL and
    whether it is confirmed (the leading one as the alarm's class, ``confirmed``; another
    as present beside it) and whether its own feature named it (beyond the leading mode's
    cross-talk, its own probability below the threshold)."""
    if not out.modes:
        return None
    own, ruls = out.mode_probabilities or {}, out.ruls
    by_feature = named_by_feature(out.modes, own)
    return [{"mode": m, "probability": _finite(own.get(m)),
             "rul_median_flights": _finite(ruls[m].median) if m in ruls else None,
             "confirmed": m == confirmed or m in out.confirmed_modes,
             "by_feature": m in by_feature}
            for m in out.modes]


def _store_alarm(session: Session, flight: Flight, act: Actuator, out: ActuatorOutcome,
                 rul: RulDistribution | None) -> None:
    """A new alarm is opened (its class at raising kept: ``Alarm.raised_fault_mode``); an
    open one follows the actuator's latest class, RUL and ambiguity group, each change of its
    leading class recorded as an alarm event, and so is the flight that confirmed its class."""
    prob = (out.class_probabilities or {}).get(out.fault_mode or "")
    median = None if rul is None or not math.isfinite(rul.median) else float(rul.median)
    low = None if rul is None else _finite(rul.quantiles.get(RUL_LOW_QUANTILE))
    if out.new_alarm:
        alarm = Alarm(actuator_id=act.id, flight_id=flight.id, status=AlarmStatus.OPEN,
                      confidence=out.max_confidence, fault_mode=out.fault_mode,
                      class_probability=prob, features=out.alarm_features,
                      isolation=out.isolation or None,
                      rul_median_flights=median, rul_low_flights=low)
        session.add(alarm)
        session.flush()
        _confirm_class(session, flight, alarm, out)
        alarm.modes = _modes_present(out, alarm.confirmed_fault_mode)
    elif out.alarm:
        open_alarm = session.scalar(select(Alarm).where(
            Alarm.actuator_id == act.id, Alarm.status != AlarmStatus.CLOSED)
            .order_by(Alarm.id.desc()))
        if open_alarm is not None:
            if open_alarm.fault_mode != out.fault_mode:
                session.add(AlarmEvent(alarm_id=open_alarm.id, flight_id=flight.id,
                                       flight_index=out.flight_index, kind="class_change",
                                       from_mode=open_alarm.fault_mode,
                                       to_mode=out.fault_mode))
            open_alarm.fault_mode = out.fault_mode
            open_alarm.class_probability = prob
            open_alarm.confidence = max(open_alarm.confidence, out.max_confidence)
            open_alarm.rul_median_flights = median
            open_alarm.rul_low_flights = low
            open_alarm.isolation = out.isolation or open_alarm.isolation
            _confirm_class(session, flight, open_alarm, out)
            open_alarm.modes = (_modes_present(out, open_alarm.confirmed_fault_mode)
                                or open_alarm.modes)
    session.flush()


def _confirm_class(session: Session, flight: Flight, alarm: Alarm, out: ActuatorOutcome
                   ) -> None:
    """The flight that confirmed the alarm's class (``out.confirmed``): kept on the alarm and
    as its own event; so is each mode confirmed present beside it (``out.confirmed_others``)."""
    for mode in out.confirmed_others:
        session.add(AlarmEvent(alarm_id=alarm.id, flight_id=flight.id,
                               flight_index=out.flight_index, kind="confirmed", to_mode=mode))
    if out.confirmed is None or alarm.confirmed_fault_mode is not None:
        return
    alarm.confirmed_fault_mode = out.confirmed
    session.add(AlarmEvent(alarm_id=alarm.id, flight_id=flight.id,
                           flight_index=out.flight_index, kind="confirmed",
                           to_mode=out.confirmed))


def _finite(v: float | None) -> float | None:
    return None if v is None or not math.isfinite(float(v)) else float(v)
