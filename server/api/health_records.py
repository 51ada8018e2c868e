"""Actuator health: feature/detection history, prognoses (RUL cone), fleet grid, alarms."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Query

from server.api.deps import Admin, Reader, SessionDep
from server.api.openapi import errors
from server.schemas import (
    AlarmAction,
    AlarmEventRead,
    AlarmRead,
    AlarmStatusFilter,
    GridCellRead,
    HealthRecordRead,
    IdPath,
    ModePresentRead,
    Offset,
    Page,
    PrognosisRead,
    SensorFlightRead,
)
from server.services import health as service

router = APIRouter(tags=["health"])


def alarm_read(row: service.AlarmRow) -> AlarmRead:
    alarm, actuator, u = row.alarm, row.actuator, row.urgency
    return AlarmRead(id=alarm.id, aircraft=row.tail, position=actuator.position,
                     actuator_id=actuator.id, flight_id=alarm.flight_id, status=alarm.status,
                     urgency=None if u is None else u.bucket,
                     urgency_label=None if u is None else u.label,
                     act_within_flights=None if u is None else u.within_flights,
                     confidence=alarm.confidence, fault_mode=alarm.fault_mode,
                     raised_fault_mode=alarm.raised_fault_mode, isolation=alarm.isolation,
                     modes=None if alarm.modes is None
                     else [ModePresentRead.model_validate(m) for m in alarm.modes],
                     confirmed_fault_mode=alarm.confirmed_fault_mode,
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
def health(actuator_id: IdPath, session: SessionDep, _: Reader,
           limit: Annotated[int, Query(ge=1, le=5000)] = 500) -> list[HealthRecordRead]:
    return [HealthRecordRead.model_validate(r) for r in
            service.health_records(session=session, actuator_id=actuator_id, limit=limit)]


@router.get("/actuators/{actuator_id}/prognoses", response_model=list[PrognosisRead],
            summary="RUL predictions after each flight (the RUL cone)")
def prognoses(actuator_id: IdPath, session: SessionDep, _: Reader,
              limit: Annotated[int, Query(ge=1, le=5000)] = 500) -> list[PrognosisRead]:
    return [PrognosisRead.model_validate(r) for r in
            service.prognoses(session=session, actuator_id=actuator_id, limit=limit)]


@router.get("/actuators/{actuator_id}/sensor-findings", response_model=list[SensorFlightRead],
            summary="Sensor advisories: flights whose signal quality left its healthy band")
def sensor_findings(actuator_id: IdPath, session: SessionDep, _: Reader,
                    limit: Annotated[int, Query(ge=1, le=5000)] = 500
                    ) -> list[SensorFlightRead]:
    return [SensorFlightRead(**f.__dict__) for f in
            service.sensor_findings(session=session, actuator_id=actuator_id, limit=limit)]


@router.get("/fleet/health", response_model=list[GridCellRead],
            summary="Fleet grid: every installed actuator green / amber / red with median RUL")
def fleet(session: SessionDep, _: Reader, base: str | None = None) -> list[GridCellRead]:
    return service.fleet_grid(session=session, base=base)


@router.get("/alarms", response_model=Page[AlarmRead],
            summary="Alarm inbox: not closed first, then by urgency bucket (replace now, act "
                    "within N flights, monitor, deferred)")
def alarms(session: SessionDep, _: Reader,
           status: AlarmStatusFilter = None,
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
def alarm_events(alarm_id: IdPath, session: SessionDep, _: Reader) -> list[AlarmEventRead]:
    service.get_alarm(session=session, alarm_id=alarm_id)  # 404 for an unknown one
    return [AlarmEventRead.model_validate(e)
            for e in service.alarm_events(session=session, alarm_ids=[alarm_id])]


@router.post("/alarms/{alarm_id}/acknowledge", response_model=AlarmRead, responses=errors(409),
             summary="Acknowledge an open alarm with a note (admin)")
def acknowledge(alarm_id: IdPath, body: AlarmAction, session: SessionDep, key: Admin) -> AlarmRead:
    service.acknowledge_alarm(session=session, alarm_id=alarm_id, by=key.name, note=body.note)
    session.commit()
    return _one(session, alarm_id)


@router.post("/alarms/{alarm_id}/close", response_model=AlarmRead, responses=errors(409),
             summary="Close an alarm with a note (admin)")
def close(alarm_id: IdPath, body: AlarmAction, session: SessionDep, key: Admin) -> AlarmRead:
    service.close_alarm(session=session, alarm_id=alarm_id, by=key.name, note=body.note)
    session.commit()
    return _one(session, alarm_id)
