"""Per-flight analysis (the ``analyze_flight`` job): the PHM chain of ``server.phm.chain``
run on one uploaded flight, with its results stored.

Steps: verify the stored bytes against their SHA-256; decode; features of the whole aircraft;
for each installed actuator advance detection, classification and prognosis from its stored
state; write health records, the new state, alarms and prognoses, and mark the flight analysed
-- all in one transaction. A job that runs twice (a worker died after committing, before
marking the job done) finds the flight's health records and writes nothing again.
"""

from __future__ import annotations

import hashlib
import math
import threading
from typing import Any

import numpy as np
from sqlalchemy import select, update

from server.flightlog import FlightLogError, read_flightlog
from server.jobs.queue import ClaimedJob
from server.jobs.worker import Deferred, JobContext
from server.models import (
    Actuator,
    ActuatorState,
    Aircraft,
    Alarm,
    Flight,
    HealthRecord,
    ModelVersion,
    Prognosis,
    utcnow,
)
from server.phm.chain import ActuatorHealth, ActuatorOutcome, PhmModel, analyze_flight
from server.phm.features import flight_features

__all__ = ["analyze_flight_job", "load_active_model"]


#: the decoded active model, keyed by (database URL, model version id): a version id alone
#: names another model in another database served by the same process
_MODEL_CACHE: dict[tuple[str, int], PhmModel] = {}
_CACHE_LOCK = threading.Lock()


def load_active_model(session: Any) -> tuple[int, PhmModel] | None:
    row = session.scalar(select(ModelVersion.id).where(ModelVersion.active.is_(True)))
    if row is None:
        return None
    key = (str(session.get_bind().url), int(row))
    with _CACHE_LOCK:
        if key not in _MODEL_CACHE:
            payload = session.get(ModelVersion, row).payload
            _MODEL_CACHE.clear()
            _MODEL_CACHE[key] = PhmModel.from_dict(payload)
        return row, _MODEL_CACHE[key]


def _reject(ctx: JobContext, flight_id: int, reasons: list[dict[str, Any]]) -> None:
    with ctx.factory() as session:
        session.execute(update(Flight).where(Flight.id == flight_id)
                        .values(status="rejected", reasons=reasons, updated_at=utcnow()))
        session.commit()


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


def _rul_fields(outcome: ActuatorOutcome) -> dict[str, Any] | None:
    rul = outcome.rul
    if rul is None:
        return None
    quantiles = {f"{100 * float(q):g}": float(v) for q, v in rul.quantiles.items()}
    return {
        "severity_mean": float(rul.severity_mean),
        "severity_std": float(rul.severity_std),
        "rul_quantiles": quantiles,
        "p_fail_within": {str(k): float(v) for k, v in rul.p_fail_within.items()},
        "histogram": {"edges": np.asarray(rul.histogram_edges, dtype=float).tolist(),
                      "mass": np.asarray(rul.histogram_mass, dtype=float).tolist()},
        "median": float(rul.median),
    }


def analyze_flight_job(ctx: JobContext, job: ClaimedJob) -> None:
    assert job.flight_id is not None
    with ctx.factory() as session:
        flight = session.get(Flight, job.flight_id)
        if flight is None or flight.status in ("analyzed", "rejected"):
            return
        blob_path, sha, kind, meta = (flight.blob_path, flight.sha256, flight.content_kind,
                                      dict(flight.flight_metadata))
        aircraft_id = flight.aircraft_id
        try:
            active = load_active_model(session)
        except ValueError as exc:  # e.g. a model of an older chain format: wait, lose nothing
            raise Deferred(f"The active model cannot analyse flights: {exc}.") from exc
        if active is None:
            raise Deferred("No active model version: train one with `hmsm train` or "
                           "POST /api/v1/models/train.")
        session.execute(update(Flight).where(Flight.id == job.flight_id)
                        .values(status="analyzing", updated_at=utcnow()))
        session.commit()
    model_id, model = active

    data = ctx.blobs.read(blob_path)
    if hashlib.sha256(data).hexdigest() != sha:
        # The bytes changed on disk after ingest: nothing to retry, the flight is unusable.
        _reject(ctx, job.flight_id, [{
            "code": "blob_corrupt", "message": "The stored file no longer matches its SHA-256; "
            "it was corrupted on disk after upload.", "details": {"sha256": sha}}])
        return
    try:
        log = read_flightlog(data, kind=kind, metadata=meta)
    except FlightLogError as exc:
        _reject(ctx, job.flight_id, [i.as_dict() for i in exc.issues])
        return
    channels = {k: np.asarray(v, dtype=np.float64) for k, v in log.channels.items()}
    features = flight_features(channels)

    with ctx.factory() as session:
        flight = session.get(Flight, job.flight_id)
        actuators = session.scalars(select(Actuator).where(
            Actuator.aircraft_id == aircraft_id, Actuator.removed_at.is_(None))).all()
        done = set(session.scalars(select(HealthRecord.actuator_id).where(
            HealthRecord.flight_id == job.flight_id)))
        todo = [a for a in actuators if a.id not in done]
        states = {a.id: session.get(ActuatorState, a.id) for a in todo}
        health = {a.position: (ActuatorHealth.from_dict(states[a.id].detection)
                               if states[a.id] is not None and states[a.id].detection
                               else model.new_health(a.position)) for a in todo}
        aircraft = session.get(Aircraft, aircraft_id)
        outcomes = analyze_flight(model, features, health, seed=job.flight_id,
                                  started_at=flight.started_at,  # aware (UTCDateTime)
                                  base=None if aircraft is None else aircraft.base)
        for act in todo:
            out = outcomes[act.position]
            _store(session, flight, act, out, health[act.position], states[act.id], model_id)
        flight.status = "analyzed"
        flight.updated_at = utcnow()
        session.commit()


def _store(session: Any, flight: Flight, act: Actuator, out: ActuatorOutcome,
           health: ActuatorHealth, state: ActuatorState | None, model_id: int) -> None:
    session.add(HealthRecord(
        actuator_id=act.id, flight_id=flight.id, model_version_id=model_id,
        flight_index=out.flight_index, started_at=flight.started_at,
        features=json_safe(out.features),
        scores=json_safe({"z": out.z, "confidence": out.confidence,
                          "alarm_features": out.alarm_features}),
        confidence=out.max_confidence, alarm=out.alarm,
        class_probabilities=json_safe(out.class_probabilities)))
    doc = json_safe(health.to_dict())
    doc["confidence"] = out.max_confidence
    if state is None:
        state = ActuatorState(actuator_id=act.id)
        session.add(state)
    state.detection = doc
    state.flights_seen = out.flight_index
    state.last_flight_id = flight.id
    state.fault_mode = out.fault_mode
    state.updated_at = utcnow()

    rul = json_safe(_rul_fields(out))
    if rul is not None and out.fault_mode is not None:
        session.add(Prognosis(actuator_id=act.id, flight_id=flight.id,
                              flight_index=out.flight_index, fault_mode=out.fault_mode,
                              severity_mean=rul["severity_mean"],
                              severity_std=rul["severity_std"],
                              rul_quantiles=rul["rul_quantiles"],
                              p_fail_within=rul["p_fail_within"], histogram=rul["histogram"]))
    prob = (out.class_probabilities or {}).get(out.fault_mode or "")
    if out.new_alarm:
        session.add(Alarm(actuator_id=act.id, flight_id=flight.id, status="open",
                          confidence=out.max_confidence, fault_mode=out.fault_mode,
                          class_probability=prob, features=out.alarm_features,
                          rul_median_flights=None if rul is None else rul["median"]))
    elif out.alarm:
        open_alarm = session.scalar(select(Alarm).where(
            Alarm.actuator_id == act.id, Alarm.status != "closed").order_by(Alarm.id.desc()))
        if open_alarm is not None:
            open_alarm.fault_mode = out.fault_mode
            open_alarm.class_probability = prob
            open_alarm.confidence = max(open_alarm.confidence, out.max_confidence)
            median = None if rul is None else rul["median"]
            open_alarm.rul_median_flights = (median if median is not None and
                                             math.isfinite(median) else None)
    session.flush()
