"""Actuator health: feature/detection history, prognoses (RUL cone), fleet grid, alarms."""

from __future__ import annotations

from datetime import datetime
from typing import Annotated, Any

from fastapi import APIRouter, Query
from pydantic import BaseModel, ConfigDict, Field

from server.api.deps import Admin, Reader, SessionDep
from server.api.openapi import errors
from server.schemas import Offset, Page
from server.services import health as service

router = APIRouter(tags=["health"])


class HealthRecordRead(BaseModel):
    model_config = ConfigDict(from_attributes=True)
    flight_id: int
    flight_index: int
    started_at: datetime | None
    features: dict[str, Any]
    scores: dict[str, Any]
    confidence: float
    alarm: bool
    class_probabilities: dict[str, float | None] | None


class RulDistributionRead(BaseModel):
    """The particle filter's RUL distribution document (``RulDistribution.to_dict``)."""

    version: int
    kind: str
    flight_index: int | None
    quantiles: list[tuple[float, float | None]] = Field(
        description="[level (fraction), RUL [flights]] pairs; null beyond the horizon")
    mean: float | None
    p_fail_within: list[tuple[int, float]] = Field(
        description="[horizon [flights], probability of failure within it] pairs")
    p_beyond_horizon: float
    histogram_edges: list[float]
    histogram_mass: list[float]
    severity_mean: float
    severity_std: float
    most_probable: float | None = None
    hours_per_flight: float | None = None


class PrognosisRead(BaseModel):
    model_config = ConfigDict(from_attributes=True)
    flight_id: int
    flight_index: int
    fault_mode: str
    distribution: RulDistributionRead
    created_at: datetime


class AlarmRead(BaseModel):
    id: int
    aircraft: str
    position: str
    actuator_id: int
    flight_id: int
    status: str
    urgency: str | None = Field(description="replace_now | act_within | monitor | deferred; "
                                "the inbox order (server/services/urgency.py); null once the "
                                "alarm is closed (a closed alarm claims no live urgency)")
    urgency_label: str | None
    act_within_flights: int | None
    confidence: float
    fault_mode: str | None = Field(description="the leading class now (it follows the "
                                   "evidence while the alarm is not closed)")
    raised_fault_mode: str | None = Field(description="the leading class when the alarm was "
                                          "raised; later changes are its events")
    class_probability: float | None
    features: list[str]
    rul_median_flights: float | None = Field(description="median of the latest RUL; 0 once "
                                             "the unit has failed")
    rul_low_flights: float | None = Field(description="5 % quantile of the latest RUL; 0 once "
                                          "the unit has failed")
    created_at: datetime
    acknowledged_by: str | None
    acknowledged_at: datetime | None
    closed_by: str | None
    closed_at: datetime | None
    note: str | None
    resolution: str | None = Field(description="replaced | no_fault_found | closed")
    deferred_until_flight: int | None
    deferred_until: datetime | None
    deferral_expired: bool


class AlarmEventRead(BaseModel):
    model_config = ConfigDict(from_attributes=True)
    alarm_id: int
    kind: str = Field(description="class_change: the leading class went from from_mode to "
                      "to_mode on this flight")
    flight_id: int | None
    flight_index: int | None
    from_mode: str | None
    to_mode: str | None
    created_at: datetime


class AlarmAction(BaseModel):
    model_config = ConfigDict(extra="forbid")
    note: str | None = Field(None, max_length=2000)


class SensorFindingRead(BaseModel):
    """A channel whose signal-quality figure left its healthy band (server/phm/sensor_health.py)."""

    channel: str = Field(description='"<position>.<signal>", e.g. "WT.x" (the LVDT)')
    sensor: str = Field(description="current | voltage | resolver | lvdt")
    metric: str = Field(description="noise (floor, rms) | offset (LVDT against the motor "
                        "shaft, m) | lsb (quantisation step) | stuck | saturated (share)")
    value: float | None
    low: float | None = Field(description="healthy band, learned on the design campaign")
    high: float | None


class SensorFlightRead(BaseModel):
    flight_id: int
    flight_index: int
    started_at: datetime | None
    findings: list[SensorFindingRead]
    set_aside: list[str] = Field(description="features not judged on this flight")
    widened: dict[str, float] = Field(
        description="features judged with a widened flight scatter: added variance [z^2]")


class GridCellRead(BaseModel):
    tail: str
    base: str
    position: str
    actuator_id: int
    serial: str
    status: str = Field(description="the urgency's colour: red | amber | yellow | grey | green")
    urgency: str
    urgency_label: str
    act_within_flights: int | None
    failed_at_flight: int | None
    confidence: float
    fault_mode: str | None
    rul_median: float | None
    rul_low: float | None
    open_alarm_id: int | None
    flights_seen: int
    sensor_findings: list[SensorFindingRead] = Field(
        description="sensor advisory: findings of the latest analysed flight")


def alarm_read(row: service.AlarmRow) -> AlarmRead:
    alarm, actuator, u = row.alarm, row.actuator, row.urgency
    return AlarmRead(id=alarm.id, aircraft=row.tail, position=actuator.position,
                     actuator_id=actuator.id, flight_id=alarm.flight_id, status=alarm.status,
                     urgency=None if u is None else u.bucket,
                     urgency_label=None if u is None else u.label,
                     act_within_flights=None if u is None else u.within_flights,
                     confidence=alarm.confidence, fault_mode=alarm.fault_mode,
                     raised_fault_mode=alarm.raised_fault_mode,
                     class_probability=alarm.class_probability, features=alarm.features,
                     rul_median_flights=row.rul_median, rul_low_flights=row.rul_low,
                     created_at=alarm.created_at,
                     acknowledged_by=alarm.acknowledged_by,
                     acknowledged_at=alarm.acknowledged_at, closed_by=alarm.closed_by,
                     closed_at=alarm.closed_at, note=alarm.note, resolution=alarm.resolution,
                     deferred_until_flight=alarm.deferred_until_flight,
                     deferred_until=alarm.deferred_until,
                     deferral_expired=row.deferral_expired)


@router.get("/actuators/{actuator_id}/health", response_model=list[HealthRecordRead],
            summary="Feature values, detection confidence and class probabilities per flight")
def health(actuator_id: int, session: SessionDep, _: Reader,
           limit: Annotated[int, Query(ge=1, le=5000)] = 500) -> list[HealthRecordRead]:
    return [HealthRecordRead.model_validate(r) for r in
            service.health_records(session=session, actuator_id=actuator_id, limit=limit)]


@router.get("/actuators/{actuator_id}/prognoses", response_model=list[PrognosisRead],
            summary="RUL predictions after each flight (the RUL cone)")
def prognoses(actuator_id: int, session: SessionDep, _: Reader,
              limit: Annotated[int, Query(ge=1, le=5000)] = 500) -> list[PrognosisRead]:
    return [PrognosisRead.model_validate(r) for r in
            service.prognoses(session=session, actuator_id=actuator_id, limit=limit)]


@router.get("/actuators/{actuator_id}/sensor-findings", response_model=list[SensorFlightRead],
            summary="Sensor advisories: flights whose signal quality left its healthy band")
def sensor_findings(actuator_id: int, session: SessionDep, _: Reader,
                    limit: Annotated[int, Query(ge=1, le=5000)] = 500
                    ) -> list[SensorFlightRead]:
    return [SensorFlightRead(**f.__dict__) for f in
            service.sensor_findings(session=session, actuator_id=actuator_id, limit=limit)]


@router.get("/fleet/health", response_model=list[GridCellRead],
            summary="Fleet grid: every installed actuator green / amber / red with median RUL")
def fleet(session: SessionDep, _: Reader, base: str | None = None) -> list[GridCellRead]:
    return [GridCellRead(**c.__dict__) for c in service.fleet_grid(session=session, base=base)]


@router.get("/alarms", response_model=Page[AlarmRead],
            summary="Alarm inbox: not closed first, then by urgency bucket (replace now, act "
                    "within N flights, monitor, deferred)")
def alarms(session: SessionDep, _: Reader,
           status: Annotated[str | None, Query(pattern="^(open|acknowledged|closed)$")] = None,
           aircraft: str | None = None,
           limit: Annotated[int, Query(ge=1, le=500)] = 100,
           offset: Offset = 0) -> Page[AlarmRead]:
    rows, total = service.list_alarms(session=session, status=status, tail=aircraft,
                                      limit=limit, offset=offset)
    return Page(items=[alarm_read(r) for r in rows], total=total, limit=limit, offset=offset)


def _one(session: SessionDep, alarm_id: int) -> AlarmRead:
    return alarm_read(service.alarm_row(session=session, alarm_id=alarm_id))


@router.get("/alarms/{alarm_id}/events", response_model=list[AlarmEventRead],
            responses=errors(404),
            summary="What happened to an alarm after it was raised (leading-class changes)")
def alarm_events(alarm_id: int, session: SessionDep, _: Reader) -> list[AlarmEventRead]:
    service.get_alarm(session=session, alarm_id=alarm_id)  # 404 for an unknown one
    return [AlarmEventRead.model_validate(e)
            for e in service.alarm_events(session=session, alarm_ids=[alarm_id])]


@router.post("/alarms/{alarm_id}/acknowledge", response_model=AlarmRead, responses=errors(409),
             summary="Acknowledge an open alarm with a note (admin)")
def acknowledge(alarm_id: int, body: AlarmAction, session: SessionDep, key: Admin) -> AlarmRead:
    service.acknowledge_alarm(session=session, alarm_id=alarm_id, by=key.name, note=body.note)
    session.commit()
    return _one(session, alarm_id)


@router.post("/alarms/{alarm_id}/close", response_model=AlarmRead, responses=errors(409),
             summary="Close an alarm with a note (admin)")
def close(alarm_id: int, body: AlarmAction, session: SessionDep, key: Admin) -> AlarmRead:
    service.close_alarm(session=session, alarm_id=alarm_id, by=key.name, note=body.note)
    session.commit()
    return _one(session, alarm_id)
