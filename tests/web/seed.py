"""``seed_results``: analysis results written straight through the ORM, for dashboard tests.

This stands in for a real simulated run (flights uploaded, analysed by
``server.jobs.pipeline.analyze_flight_job`` with an active model) until the pipeline is fast
enough to run in the browser tests; swap the body for that run when it is. The shapes follow
what the analysis stores (``server/services/analysis.py``): health records with
``scores = {"z", "confidence", "alarm_features"}``, prognoses with the filter's
``RulDistribution.to_dict`` document, and a model version whose ``metrics["confusion"]``
is :func:`server.phm.classification.confusion`'s output.
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass
from datetime import datetime, timedelta, timezone
from typing import Any

import numpy as np
from sqlalchemy import select, update
from sqlalchemy.orm import Session, sessionmaker

from server.demo_model import load_demo_model
from server.models import (
    Actuator,
    ActuatorState,
    Aircraft,
    Alarm,
    AlarmEvent,
    Flight,
    GroundTruth,
    HealthRecord,
    Injection,
    ModelVersion,
    Prognosis,
)
from server.phm.prognosis import RulDistribution
from server.services import models as model_service

__all__ = ["SeedResult", "seed_results", "add_alarm", "seed_class_change", "CONFUSION"]

CLASSES = ["BDO", "DMD", "MTEL", "MTWEAR", "REWEAR", "SE", "TTS"]
_COUNTS = [[9, 0, 0, 0, 0, 1, 0], [0, 8, 1, 1, 0, 0, 0], [0, 1, 7, 2, 0, 0, 0],
           [0, 0, 2, 8, 0, 0, 0], [0, 0, 0, 0, 10, 0, 0], [1, 0, 0, 0, 0, 9, 0],
           [0, 1, 0, 0, 0, 0, 9]]
CONFUSION = {
    "classes": CLASSES,
    "counts": _COUNTS,
    "rates": [[c / sum(row) for c in row] for row in _COUNTS],
    "support": [sum(row) for row in _COUNTS],
    "recall": [_COUNTS[i][i] / sum(_COUNTS[i]) for i in range(7)],
    "precision": [_COUNTS[i][i] / sum(r[i] for r in _COUNTS) for i in range(7)],
    "accuracy": sum(_COUNTS[i][i] for i in range(7)) / sum(map(sum, _COUNTS)),
    "n": sum(map(sum, _COUNTS)),
}
FEATURES = ["WL1.F_TTS", "WL1.F_DMD", "WL1.F_SE", "WL1.F_BDO", "WL1.F_MTEL", "WL1.F_MTWEAR",
            "WL1.F_REWEAR"]


@dataclass(frozen=True)
class SeedResult:
    model_id: int
    actuator_id: int
    alarm_id: int
    injection_id: int
    n_flights: int



def rul_document(flight_index: int, median: float, severity: float, severity_std: float,
                 edges: list[float], mass: list[float],
                 spread: tuple[float, float, float, float] = (0.6, 0.85, 1.15, 1.45)) -> dict:
    """An RUL distribution's JSON document, made by the class the filter returns: the 5, 25,
    75 and 95 % quantiles at ``spread`` times the median."""
    q05, q25, q75, q95 = (median * f for f in spread)
    return RulDistribution(
        flight_index=flight_index,
        quantiles={0.05: q05, 0.25: q25, 0.5: median, 0.75: q75, 0.95: q95},
        mean=median, p_fail_within={10: 0.05, 25: 0.3}, p_beyond_horizon=0.0,
        histogram_edges=np.asarray(edges), histogram_mass=np.asarray(mass),
        severity_mean=severity, severity_std=severity_std).to_dict()


def _flight(session: Session, aircraft: Aircraft, code: str, started: datetime) -> Flight:
    sha = hashlib.sha256(f"{aircraft.tail}/{code}".encode()).hexdigest()
    row = Flight(aircraft_id=aircraft.id, tail=aircraft.tail, flight_code=code,
                 status="analyzed", reasons=[], sha256=sha, size_bytes=1,
                 blob_path=f"seed/{sha}", content_kind="seed", flight_metadata={},
                 started_at=started, block_hours=1.5)
    session.add(row)
    return row


def seed_results(factory: sessionmaker[Session], *, tail: str, position: str = "WL1",
                 n_flights: int = 40, onset: int = 15, life: int = 60) -> SeedResult:
    """A ready, active model; ``n_flights`` analysed flights of ``tail``; a DMD fault on
    ``position`` from flight ``onset`` (true failure at ``life``) detected with prognoses, an
    open alarm, and the test-station injection with its ground truth."""
    with factory() as session:
        aircraft = session.scalar(select(Aircraft).where(Aircraft.tail == tail))
        assert aircraft is not None, f"create aircraft {tail} first"
        act = session.scalar(select(Actuator).where(Actuator.aircraft_id == aircraft.id,
                                                    Actuator.position == position,
                                                    Actuator.removed_at.is_(None)))
        assert act is not None
        model = ModelVersion(name="seeded", status="ready", active=True,
                             payload={"detector": {"feature_names": FEATURES,
                                                   "band": [[3.2, 3.0, 3.0]] * len(FEATURES),
                                                   "alarm_confidence": 0.98}},
                             training={"seeded": True},
                             metrics={"accuracy": CONFUSION["accuracy"], "confusion": CONFUSION},
                             finished_at=datetime.now(timezone.utc))
        session.add(model)
        inj = Injection(aircraft_id=aircraft.id, position=position, fault_mode="DMD",
                        onset_flight=onset, time_to_failure_flights=life - onset,
                        status="active", created_by="seed")
        session.add(inj)
        session.flush()
        t0 = datetime(2025, 1, 1, tzinfo=timezone.utc)
        first_alarm: Alarm | None = None
        for i in range(1, n_flights + 1):
            code = f"F{i:04d}"
            flight = _flight(session, aircraft, code, t0 + timedelta(hours=6 * i))
            session.flush()
            sev = max(0.0, (i - onset) / (life - onset))
            z = {f: math.sin(i * (k + 1)) * 0.8 for k, f in enumerate(FEATURES)}
            z["WL1.F_DMD"] = 0.5 + 9.0 * sev
            alarm = i >= onset + 5
            conf = min(0.999, 0.3 + sev * 2.5) if alarm else 0.1 + 0.01 * (i % 5)
            probs = ({"DMD": 0.7 + 0.2 * sev, "MTWEAR": 0.2 - 0.1 * sev, "TTS": 0.1 - 0.1 * sev}
                     if alarm else None)
            session.add(HealthRecord(
                actuator_id=act.id, flight_id=flight.id, model_version_id=model.id,
                flight_index=i, started_at=flight.started_at,
                features={"WL1.F_DMD": {"mean": z["WL1.F_DMD"]}},
                scores={"z": z, "confidence": {"WL1.F_DMD": conf},
                        "alarm_features": ["WL1.F_DMD"] if alarm else []},
                confidence=conf, alarm=alarm, class_probabilities=probs))
            if i >= onset:
                session.add(GroundTruth(injection_id=inj.id, flight_code=code, flight_number=i,
                                        severity=sev, severity_norm=sev,
                                        true_rul_flights=life - i))
            if alarm:
                true = life - i
                med = true * (1.0 + 0.3 * math.exp(-(i - onset) / 8))
                edges = [float(e) for e in range(0, 101, 5)]
                mass = [math.exp(-0.5 * ((e + 2.5 - med) / 6.0) ** 2) for e in edges[:-1]]
                total = sum(mass) or 1.0
                session.add(Prognosis(
                    actuator_id=act.id, flight_id=flight.id, flight_index=i, fault_mode="DMD",
                    distribution=rul_document(i, med, sev, 0.05 + 0.02 * (1 - sev), edges,
                                              [m / total for m in mass])))
                if first_alarm is None:
                    first_alarm = Alarm(actuator_id=act.id, flight_id=flight.id, status="open",
                                        confidence=conf, fault_mode="DMD",
                                        class_probability=probs["DMD"] if probs else None,
                                        features=["WL1.F_DMD"], rul_median_flights=med,
                                        rul_low_flights=0.6 * med)
                    session.add(first_alarm)
                else:
                    first_alarm.confidence = max(first_alarm.confidence, conf)
                    first_alarm.rul_median_flights = med
                    # the 5 % quantile, as the analysis stores it (rul_document's spread)
                    first_alarm.rul_low_flights = 0.6 * med
        session.add(ActuatorState(actuator_id=act.id, flights_seen=n_flights,
                                  detection={"confidence": conf}, fault_mode="DMD"))
        session.commit()
        assert first_alarm is not None
        return SeedResult(model_id=model.id, actuator_id=act.id, alarm_id=first_alarm.id,
                          injection_id=inj.id, n_flights=n_flights)


def add_alarm(factory: sessionmaker[Session], *, tail: str, position: str,
              fault_mode: str = "TTS", confidence: float = 0.99,
              rul: float | None = 12.0, isolation: dict[str, float] | None = None,
              modes: list[dict[str, Any]] | None = None) -> int:
    """Raise a new open alarm on an installed actuator (as the analysis job would)."""
    with factory() as session:
        aircraft = session.scalar(select(Aircraft).where(Aircraft.tail == tail))
        assert aircraft is not None
        act = session.scalar(select(Actuator).where(Actuator.aircraft_id == aircraft.id,
                                                    Actuator.position == position,
                                                    Actuator.removed_at.is_(None)))
        assert act is not None
        n = len(session.scalars(select(Flight.id).where(Flight.aircraft_id == aircraft.id)).all())
        flight = _flight(session, aircraft, f"A{n + 1:04d}", datetime.now(timezone.utc))
        session.flush()
        row = Alarm(actuator_id=act.id, flight_id=flight.id, status="open",
                    confidence=confidence, fault_mode=fault_mode, class_probability=0.8,
                    features=[f"{position}.F_{fault_mode}"], rul_median_flights=rul,
                    isolation=isolation, modes=modes)
        session.add(row)
        session.commit()
        return row.id


def seed_class_change(factory: sessionmaker[Session], seed: SeedResult, *, tail: str,
                      alarm_confidence: float = 0.95) -> None:
    """The seeded alarm raised as MTEL, its leading class DMD since flight 25 (an alarm
    event), and its actuator's health judged by a model alarming at ``alarm_confidence``."""
    doc = load_demo_model()
    doc["payload"]["detector"]["alarm_confidence"] = alarm_confidence
    with factory() as s:
        model = model_service.store_trained(session=s, name=f"alarm at {alarm_confidence}",
                                            payload=doc["payload"], report=doc["training"],
                                            make_active=False)
        s.execute(update(HealthRecord).where(HealthRecord.actuator_id == seed.actuator_id)
                  .values(model_version_id=model.id))
        alarm = s.get(Alarm, seed.alarm_id)
        assert alarm is not None
        alarm.raised_fault_mode = "MTEL"
        flight = s.scalar(select(Flight).where(Flight.tail == tail, Flight.flight_code == "F0025"))
        assert flight is not None
        s.add(AlarmEvent(alarm_id=seed.alarm_id, flight_id=flight.id, flight_index=25,
                         kind="class_change", from_mode="MTEL", to_mode="DMD"))
        s.commit()
