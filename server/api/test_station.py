"""Test station: operators inject faults into the simulated half-wing and follow ground truth."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Query

from server.api.deps import Operator, Reader, SessionDep
from server.api.openapi import errors
from server.models import (
    ConditionGroundTruth,
    GroundTruth,
    Injection,
    SensorGroundTruth,
    SensorInjection,
    SimCondition,
)
from server.schemas import (
    ConditionCreate,
    ConditionRead,
    ConditionTruthIn,
    ConditionTruthRead,
    GroundTruthIn,
    GroundTruthRead,
    IdPath,
    InjectionCreate,
    InjectionRead,
    InjectionStatus,
    Offset,
    Page,
    SensorInjectionCreate,
    SensorInjectionRead,
    SensorTruthIn,
    SensorTruthRead,
)
from server.services import conditions, fleet
from server.services import sensor_injections as sensors
from server.services import test_station as service
from server.vocabulary import SENSOR_OF_SIGNAL

router = APIRouter(prefix="/test-station", tags=["test station"])
def _read(row: Injection, tail: str, warnings: list[str] | None = None) -> InjectionRead:
    return InjectionRead(id=row.id, aircraft=tail, position=row.position,
                         fault_mode=row.fault_mode, onset_flight=row.onset_flight,
                         time_to_failure_flights=row.time_to_failure_flights,
                         severity=row.severity, status=row.status, created_by=row.created_by,
                         created_at=row.created_at, cancelled_at=row.cancelled_at,
                         failure_flight=row.failure_flight,
                         planned_failure_flight=row.planned_failure_flight,
                         warnings=warnings or [])


def _truth_read(row: GroundTruth) -> GroundTruthRead:
    return GroundTruthRead(injection_id=row.injection_id, flight=row.flight_code,
                           flight_number=row.flight_number, severity=row.severity,
                           severity_norm=row.severity_norm, true_rul_flights=row.true_rul_flights)


def _tail(session: SessionDep, row: Injection | SensorInjection | SimCondition) -> str:
    return fleet.tail_of(session=session, aircraft_id=row.aircraft_id)


@router.post("/injections", status_code=201, response_model=InjectionRead,
             responses=errors(404, 409),
             summary="Inject a fault (operator)")
def create(body: InjectionCreate, session: SessionDep, key: Operator) -> InjectionRead:
    row = service.create_injection(session=session, tail=body.aircraft, position=body.position,
                                   fault_mode=body.fault_mode, onset_flight=body.onset_flight,
                                   time_to_failure_flights=body.time_to_failure_flights,
                                   severity=body.severity, created_by=key.name)
    warning = service.span_warning(session=session, fault_mode=body.fault_mode,
                                   time_to_failure_flights=body.time_to_failure_flights)
    session.commit()
    return _read(row, body.aircraft, [warning] if warning else [])


@router.get("/injections", response_model=Page[InjectionRead], summary="List injections")
def list_(session: SessionDep, _: Reader, aircraft: str | None = None,
          status: Annotated[str | None, Query(pattern="^(pending|active|cancelled|failed)$")
                            ] = None,
          limit: Annotated[int, Query(ge=1, le=500)] = 100,
          offset: Offset = 0) -> Page[InjectionRead]:
    rows, total = service.list_injections(session=session, tail=aircraft, status=status,
                                          limit=limit, offset=offset)
    return Page(items=[_read(r, t) for r, t in rows], total=total, limit=limit, offset=offset)


@router.get("/injections/{injection_id}", response_model=InjectionRead,
            summary="One injection")
def get(injection_id: IdPath, session: SessionDep, _: Reader) -> InjectionRead:
    row = service.get_injection(session=session, injection_id=injection_id)
    return _read(row, _tail(session, row))


@router.post("/injections/{injection_id}/cancel", response_model=InjectionRead,
             responses=errors(409),
             summary="Cancel a pending or active injection (operator)")
def cancel(injection_id: IdPath, session: SessionDep, _: Operator) -> InjectionRead:
    row = service.cancel_injection(session=session, injection_id=injection_id)
    session.commit()
    return _read(row, _tail(session, row))


@router.post("/injections/{injection_id}/status", response_model=InjectionRead,
             responses=errors(409),
             summary="Sim worker: the fault started or reached failure (operator)")
def set_status(injection_id: IdPath, body: InjectionStatus, session: SessionDep, _: Operator
               ) -> InjectionRead:
    row = service.update_injection_status(session=session, injection_id=injection_id,
                                          status=body.status, failure_flight=body.failure_flight,
                                          planned_failure_flight=body.planned_failure_flight)
    session.commit()
    return _read(row, _tail(session, row))


@router.put("/injections/{injection_id}/ground-truth", response_model=GroundTruthRead,
            summary="Sim worker: true severity of one flight (operator; idempotent)")
def report(injection_id: IdPath, body: GroundTruthIn, session: SessionDep, _: Operator
           ) -> GroundTruthRead:
    row = service.report_ground_truth(session=session, injection_id=injection_id,
                                      flight_code=body.flight, flight_number=body.flight_number,
                                      severity=body.severity, severity_norm=body.severity_norm,
                                      true_rul_flights=body.true_rul_flights)
    session.commit()
    return _truth_read(row)


@router.get("/injections/{injection_id}/ground-truth", response_model=list[GroundTruthRead],
            summary="Ground truth of an injection, flight by flight")
def ground_truth(injection_id: IdPath, session: SessionDep, _: Reader) -> list[GroundTruthRead]:
    return [_truth_read(r) for r in service.list_ground_truth(session=session,
                                                              injection_id=injection_id)]


# ---- sensor injections (a table of their own: see server/services/sensor_injections.py) ---

def _sensor_read(row: SensorInjection, tail: str) -> SensorInjectionRead:
    channels = [f"{row.position}.{s}" for s, of in SENSOR_OF_SIGNAL.items() if of == row.sensor]
    return SensorInjectionRead(
        id=row.id, aircraft=tail, position=row.position, sensor=row.sensor, channels=channels,
        kind=row.kind, value=row.value, onset_flight=row.onset_flight,
        started_flight=row.started_flight, status=row.status, created_by=row.created_by,
        created_at=row.created_at, cancelled_at=row.cancelled_at)


@router.post("/sensor-injections", status_code=201, response_model=SensorInjectionRead,
             responses=errors(404, 409), summary="Degrade a sensor (operator)")
def create_sensor(body: SensorInjectionCreate, session: SessionDep, key: Operator
                  ) -> SensorInjectionRead:
    row = sensors.create(session=session, tail=body.aircraft, position=body.position,
                         sensor=body.sensor, kind=body.kind, value=body.value,
                         onset_flight=body.onset_flight, created_by=key.name)
    session.commit()
    return _sensor_read(row, body.aircraft)


@router.get("/sensor-injections", response_model=Page[SensorInjectionRead],
            summary="List sensor injections")
def list_sensor(session: SessionDep, _: Reader, aircraft: str | None = None,
                status: Annotated[str | None, Query(pattern="^(pending|active|cancelled)$")
                                  ] = None,
                limit: Annotated[int, Query(ge=1, le=500)] = 100,
                offset: Offset = 0) -> Page[SensorInjectionRead]:
    rows, total = sensors.list_(session=session, tail=aircraft, status=status, limit=limit,
                                offset=offset)
    return Page(items=[_sensor_read(r, t) for r, t in rows], total=total, limit=limit,
                offset=offset)


@router.get("/sensor-injections/{injection_id}", response_model=SensorInjectionRead,
            summary="One sensor injection")
def get_sensor(injection_id: IdPath, session: SessionDep, _: Reader) -> SensorInjectionRead:
    row = sensors.get(session=session, injection_id=injection_id)
    return _sensor_read(row, _tail(session, row))


@router.post("/sensor-injections/{injection_id}/cancel", response_model=SensorInjectionRead,
             responses=errors(409), summary="Cancel a pending or active sensor injection "
             "(operator)")
def cancel_sensor(injection_id: IdPath, session: SessionDep, _: Operator) -> SensorInjectionRead:
    row = sensors.cancel(session=session, injection_id=injection_id)
    session.commit()
    return _sensor_read(row, _tail(session, row))


@router.put("/sensor-injections/{injection_id}/ground-truth", response_model=SensorTruthRead,
            summary="Sim worker: what the sensor injection did to one flight (operator; "
            "idempotent; the first report makes it active)")
def report_sensor(injection_id: IdPath, body: SensorTruthIn, session: SessionDep, _: Operator
                  ) -> SensorTruthRead:
    row = sensors.report_truth(session=session, injection_id=injection_id,
                               flight_code=body.flight, flight_number=body.flight_number,
                               applied=body.applied)
    session.commit()
    return _sensor_truth_read(row)


@router.get("/sensor-injections/{injection_id}/ground-truth",
            response_model=list[SensorTruthRead],
            summary="Ground truth of a sensor injection, flight by flight")
def sensor_truth(injection_id: IdPath, session: SessionDep, _: Reader) -> list[SensorTruthRead]:
    return [_sensor_truth_read(r) for r in sensors.list_truth(session=session,
                                                              injection_id=injection_id)]


def _sensor_truth_read(row: SensorGroundTruth) -> SensorTruthRead:
    return SensorTruthRead(sensor_injection_id=row.sensor_injection_id, flight=row.flight_code,
                           flight_number=row.flight_number, applied=row.applied)


# ---- simulation conditions on an aircraft (server/services/conditions.py) --------------------

def _condition_read(row: SimCondition, tail: str) -> ConditionRead:
    return ConditionRead(id=row.id, aircraft=tail, kind=row.kind, value=row.value, base=row.base,
                         onset_flight=row.onset_flight, started_flight=row.started_flight,
                         status=row.status, created_by=row.created_by,
                         created_at=row.created_at, cancelled_at=row.cancelled_at)


def _condition_truth_read(row: ConditionGroundTruth) -> ConditionTruthRead:
    return ConditionTruthRead(condition_id=row.condition_id, flight=row.flight_code,
                              flight_number=row.flight_number, applied=row.applied)


@router.post("/conditions", status_code=201, response_model=ConditionRead,
             responses=errors(404, 409), summary="Set a simulation condition on an aircraft "
             "(operator)")
def create_condition(body: ConditionCreate, session: SessionDep, key: Operator
                     ) -> ConditionRead:
    row = conditions.create(session=session, tail=body.aircraft, kind=body.kind,
                            value=body.value, base=body.base, onset_flight=body.onset_flight,
                            created_by=key.name)
    session.commit()
    return _condition_read(row, body.aircraft)


@router.get("/conditions", response_model=Page[ConditionRead], summary="List conditions")
def list_conditions(session: SessionDep, _: Reader, aircraft: str | None = None,
                    status: Annotated[str | None, Query(pattern="^(pending|active|cancelled)$")
                                      ] = None,
                    limit: Annotated[int, Query(ge=1, le=500)] = 100,
                    offset: Offset = 0) -> Page[ConditionRead]:
    rows, total = conditions.list_(session=session, tail=aircraft, status=status, limit=limit,
                                   offset=offset)
    return Page(items=[_condition_read(r, t) for r, t in rows], total=total, limit=limit,
                offset=offset)


@router.get("/conditions/{condition_id}", response_model=ConditionRead,
            summary="One condition")
def get_condition(condition_id: IdPath, session: SessionDep, _: Reader) -> ConditionRead:
    row = conditions.get(session=session, condition_id=condition_id)
    return _condition_read(row, _tail(session, row))


@router.post("/conditions/{condition_id}/cancel", response_model=ConditionRead,
             responses=errors(409), summary="Cancel a pending or active condition (operator)")
def cancel_condition(condition_id: IdPath, session: SessionDep, _: Operator) -> ConditionRead:
    row = conditions.cancel(session=session, condition_id=condition_id)
    session.commit()
    return _condition_read(row, _tail(session, row))


@router.put("/conditions/{condition_id}/ground-truth", response_model=ConditionTruthRead,
            summary="Sim worker: what the condition did to one flight (operator; idempotent; "
            "the first report makes it active)")
def report_condition(condition_id: IdPath, body: ConditionTruthIn, session: SessionDep,
                     _: Operator) -> ConditionTruthRead:
    row = conditions.report_truth(session=session, condition_id=condition_id,
                                  flight_code=body.flight, flight_number=body.flight_number,
                                  applied=body.applied)
    session.commit()
    return _condition_truth_read(row)


@router.get("/conditions/{condition_id}/ground-truth", response_model=list[ConditionTruthRead],
            summary="Ground truth of a condition, flight by flight")
def condition_truth(condition_id: IdPath, session: SessionDep, _: Reader
                    ) -> list[ConditionTruthRead]:
    return [_condition_truth_read(r) for r in conditions.list_truth(
        session=session, condition_id=condition_id)]
