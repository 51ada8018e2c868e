"""ORM models (SQLAlchemy 2.0 typed mapping). Alembic migrations are the only way they reach a
database; ``tests/test_migrations.py`` checks that the two never drift.

Times are timezone-aware UTC everywhere (SQLite keeps no zone, :class:`UTCDateTime` restores it).
"""

from __future__ import annotations

import hashlib
import json
from datetime import datetime, timezone
from enum import StrEnum
from typing import Any

from sqlalchemy import (
    JSON,
    BigInteger,
    DateTime,
    Enum,
    Float,
    ForeignKey,
    Index,
    Integer,
    MetaData,
    String,
    Text,
    TypeDecorator,
    UniqueConstraint,
    text,
)
from sqlalchemy.orm import DeclarativeBase, Mapped, mapped_column, relationship

from server.vocabulary import (
    FAULT_MODES,
    STATION_LIVE,
    AlarmStatus,
    FlightStatus,
    JobStatus,
    ModelVersionStatus,
    StationStatus,
)

__all__ = [
    "JobKind",
    "Base",
    "Aircraft",
    "Actuator",
    "Flight",
    "Job",
    "ApiKey",
    "ROLES",
    "utcnow",
    "upload_key_of",
    "ModelVersion",
    "HealthRecord",
    "ActuatorState",
    "Alarm",
    "Prognosis",
    "StationItem",
    "FlightTruth",
    "Injection",
    "GroundTruth",
    "ALARM_RESOLUTIONS",
    "MAINTENANCE_KINDS",
    "MaintenanceAction",
    "AlarmEvent",
    "ALARM_EVENT_KINDS",
    "FAULT_MODES",
    "WorkerHeartbeat",
    "JobTiming",
    "JobAttempts",
]

#: viewer reads; uploader uploads flights; maintainer records maintenance actions (the line
#: maintenance engineer); operator runs the test station; admin everything
ROLES = ("viewer", "uploader", "maintainer", "operator", "admin")

NAMING = {
    "ix": "ix_%(column_0_label)s",
    "uq": "uq_%(table_name)s_%(column_0_name)s",
    "ck": "ck_%(table_name)s_%(constraint_name)s",
    "fk": "fk_%(table_name)s_%(column_0_name)s_%(referred_table_name)s",
    "pk": "pk_%(table_name)s",
}


def utcnow() -> datetime:
    return datetime.now(timezone.utc)


def upload_key_of(kind: str, sha256: str, outside_metadata: dict[str, str]) -> str:
    """SHA-256 over a file's kind, its content hash and the metadata sent beside it (none for
    Parquet, which carries its own): what makes two uploads the same one."""
    text = json.dumps([kind, sha256, outside_metadata], sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()


def _stored_upload_key(context: Any) -> str:
    """A row written without its upload's key (seeds, tests) gets the one migration 0005 gives
    existing rows: from what the row stores."""
    row = context.get_current_parameters()
    kind = row["content_kind"]
    outside = {} if kind == "parquet" else dict(row.get("flight_metadata") or {})
    return upload_key_of(kind, row["sha256"], outside)


def _class_at_insert(context: Any) -> str | None:
    """An alarm's class at raising is its class when the row is written."""
    return context.get_current_parameters().get("fault_mode")


class UTCDateTime(TypeDecorator[datetime]):
    """Stores aware datetimes as UTC; gives them back aware even where the backend drops zones."""

    impl = DateTime(timezone=True)
    cache_ok = True

    def process_bind_param(self, value: datetime | None, dialect: Any) -> datetime | None:
        if value is None:
            return None
        if value.tzinfo is None:
            raise ValueError("naive datetime given to a UTC column")
        return value.astimezone(timezone.utc)

    def process_result_value(self, value: datetime | None, dialect: Any) -> datetime | None:
        if value is None:
            return None
        return value.replace(tzinfo=timezone.utc) if value.tzinfo is None else value


def status_type(states: type[StrEnum]) -> Enum:
    """A ``status`` column of ``states``: VARCHAR(16) holding the members' values (the text
    the API shows), a CHECK constraint ``ck_<table>_status`` so that the database refuses any
    other, and rows that load as members."""
    return Enum(states, name="status", native_enum=False, create_constraint=True, length=16,
                values_callable=lambda members: [m.value for m in members],
                validate_strings=True)


def _one_live(table: str, *columns: str) -> Index:
    """At most one live test-station item per ``columns`` (the check before an insert gives
    the friendly 409; this index holds under concurrent requests)."""
    live = text("status IN (" + ", ".join(f"'{s}'" for s in STATION_LIVE) + ")")
    return Index(f"uq_{table}_live", *columns, unique=True, sqlite_where=live,
                 postgresql_where=live)


class Base(DeclarativeBase):
    metadata = MetaData(naming_convention=NAMING)


class Aircraft(Base):
    __tablename__ = "aircraft"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    tail: Mapped[str] = mapped_column(String(64), unique=True)
    base: Mapped[str] = mapped_column(String(64))
    created_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utcnow)

    actuators: Mapped[list[Actuator]] = relationship(
        back_populates="aircraft", order_by="Actuator.id"
    )


class Actuator(Base):
    """One physical actuator at one position; a replacement is a new row (fresh health history)."""

    __tablename__ = "actuators"
    __table_args__ = (
        Index(
            "uq_actuators_installed_position",
            "aircraft_id",
            "position",
            unique=True,
            sqlite_where=text("removed_at IS NULL"),
            postgresql_where=text("removed_at IS NULL"),
        ),
        Index(
            "uq_actuators_installed_serial",
            "serial",
            unique=True,
            sqlite_where=text("removed_at IS NULL"),
            postgresql_where=text("removed_at IS NULL"),
        ),
    )

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    aircraft_id: Mapped[int] = mapped_column(ForeignKey("aircraft.id"), index=True)
    position: Mapped[str] = mapped_column(String(8))
    serial: Mapped[str] = mapped_column(String(64), index=True)
    installed_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utcnow)
    removed_at: Mapped[datetime | None] = mapped_column(UTCDateTime)
    removal_note: Mapped[str | None] = mapped_column(Text)
    #: the aircraft flight number at which this unit reached failure (a state: it stays so
    #: until the unit is replaced); set when the test station reports the failure
    failed_at_flight: Mapped[int | None] = mapped_column(Integer)
    failed_at: Mapped[datetime | None] = mapped_column(UTCDateTime)

    aircraft: Mapped[Aircraft] = relationship(back_populates="actuators")


#: the flights that hold their (aircraft, flight) slot and their upload key: all but rejected
_ACCEPTED = text(f"status <> '{FlightStatus.REJECTED.value}'")


class Flight(Base):
    """One uploaded flight log. Rejected flights keep their bytes and reasons for forensics and
    hold neither their (aircraft, flight) slot nor their upload key, so the same or a corrected
    file can be sent again and is evaluated afresh (a new row).

    ``sha256`` is the content hash (blobs are content-addressed: several rows may share one);
    ``upload_key`` is what makes two uploads the same one (``services.flights.upload_key``:
    the bytes, their kind and, for CSV/MAT, the metadata sent beside them)."""

    __tablename__ = "flights"
    __table_args__ = (
        Index(
            "uq_flights_accepted_aircraft_flight",
            "aircraft_id",
            "flight_code",
            unique=True,
            sqlite_where=_ACCEPTED,
            postgresql_where=_ACCEPTED,
        ),
        Index(
            "uq_flights_accepted_upload_key",
            "upload_key",
            unique=True,
            sqlite_where=_ACCEPTED,
            postgresql_where=_ACCEPTED,
        ),
        Index("ix_flights_aircraft_started", "aircraft_id", "started_at"),
        # the rejected bytes a key stores, read before each rejected file is kept (its quota)
        Index("ix_flights_uploader_status", "uploader_key_id", "status"),
    )

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    aircraft_id: Mapped[int | None] = mapped_column(ForeignKey("aircraft.id"), index=True)
    tail: Mapped[str | None] = mapped_column(String(64))
    flight_code: Mapped[str | None] = mapped_column(String(64))
    status: Mapped[FlightStatus] = mapped_column(status_type(FlightStatus), index=True)
    reasons: Mapped[list[dict[str, Any]]] = mapped_column(JSON, default=list)
    sha256: Mapped[str] = mapped_column(String(64), index=True)
    upload_key: Mapped[str] = mapped_column(String(64), default=_stored_upload_key)
    size_bytes: Mapped[int] = mapped_column(BigInteger)
    blob_path: Mapped[str] = mapped_column(String(255))
    content_kind: Mapped[str] = mapped_column(String(16))
    flight_metadata: Mapped[dict[str, Any]] = mapped_column(JSON, default=dict)
    started_at: Mapped[datetime | None] = mapped_column(UTCDateTime)
    block_hours: Mapped[float | None] = mapped_column(Float)
    uploader_key_id: Mapped[int | None] = mapped_column(ForeignKey("api_keys.id"))
    #: when the raw log was removed by the raw-log retention (server/services/retention.py;
    #: its features and results stay); None while the bytes are kept
    raw_pruned_at: Mapped[datetime | None] = mapped_column(UTCDateTime)
    received_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utcnow)
    updated_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utcnow, onupdate=utcnow)


class JobKind(StrEnum):
    """The kinds of background work; each has one handler (``server.jobs.handlers``)."""

    ANALYZE_FLIGHT = "analyze_flight"
    TRAIN_MODEL = "train_model"


#: the jobs that hold the training slot: one ``train_model`` job queued or running at a time
#: (``POST /models/train`` answers 409 past it; this index holds under concurrent requests)
PENDING_TRAINING = text(f"kind = '{JobKind.TRAIN_MODEL.value}' AND status IN "
                        f"('{JobStatus.QUEUED.value}', '{JobStatus.RUNNING.value}')")


class Job(Base):
    """A durable unit of background work; ``lock_key`` serialises jobs of one aircraft."""

    __tablename__ = "jobs"
    __table_args__ = (
        UniqueConstraint("kind", "flight_id", name="uq_jobs_kind_flight"),
        Index("ix_jobs_claim", "status", "run_after"),
        Index("uq_jobs_pending_training", "kind", unique=True, sqlite_where=PENDING_TRAINING,
              postgresql_where=PENDING_TRAINING),
    )

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    kind: Mapped[str] = mapped_column(String(32))
    flight_id: Mapped[int | None] = mapped_column(ForeignKey("flights.id"))
    lock_key: Mapped[str] = mapped_column(String(64), index=True)
    status: Mapped[JobStatus] = mapped_column(status_type(JobStatus), default=JobStatus.QUEUED)
    attempts: Mapped[int] = mapped_column(Integer, default=0)
    max_attempts: Mapped[int] = mapped_column(Integer, default=5)
    run_after: Mapped[datetime] = mapped_column(UTCDateTime, default=utcnow)
    lease_until: Mapped[datetime | None] = mapped_column(UTCDateTime)
    locked_by: Mapped[str | None] = mapped_column(String(128))
    last_error: Mapped[str | None] = mapped_column(Text)
    payload: Mapped[dict[str, Any]] = mapped_column(JSON, default=dict)
    created_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utcnow)
    updated_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utcnow, onupdate=utcnow)
    started_at: Mapped[datetime | None] = mapped_column(UTCDateTime)
    finished_at: Mapped[datetime | None] = mapped_column(UTCDateTime)


class ApiKey(Base):
    """An API key: only its SHA-256 is stored (keys are 256-bit random, so a fast hash suffices)."""

    __tablename__ = "api_keys"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    name: Mapped[str] = mapped_column(String(128))
    role: Mapped[str] = mapped_column(String(16))
    key_hash: Mapped[str] = mapped_column(String(64), unique=True)
    prefix: Mapped[str] = mapped_column(String(16))
    created_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utcnow)
    revoked_at: Mapped[datetime | None] = mapped_column(UTCDateTime)


# ---------------------------------------------------------------------------------------------
# PHM results and the test station
# ---------------------------------------------------------------------------------------------

#: how a closed alarm was resolved: by a replacement, an inspection that found no fault (a
#: false alarm), or closed by hand
ALARM_RESOLUTIONS = ("replaced", "no_fault_found", "closed")
MAINTENANCE_KINDS = ("replace", "inspect", "defer")


class ModelVersion(Base):
    """A trained PHM model (baselines, thresholds, classifier, measurement models) as JSON."""

    __tablename__ = "model_versions"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    name: Mapped[str] = mapped_column(String(128))
    status: Mapped[ModelVersionStatus] = mapped_column(status_type(ModelVersionStatus),
                                                       default=ModelVersionStatus.TRAINING)
    active: Mapped[bool] = mapped_column(default=False)
    payload: Mapped[dict[str, Any]] = mapped_column(JSON, default=dict)
    training: Mapped[dict[str, Any]] = mapped_column(JSON, default=dict)
    metrics: Mapped[dict[str, Any]] = mapped_column(JSON, default=dict)
    error: Mapped[str | None] = mapped_column(Text)
    created_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utcnow)
    finished_at: Mapped[datetime | None] = mapped_column(UTCDateTime)


class HealthRecord(Base):
    """What one flight said about one actuator: features, detection, class probabilities."""

    __tablename__ = "health_records"
    __table_args__ = (UniqueConstraint("actuator_id", "flight_id",
                                       name="uq_health_records_actuator_flight"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    actuator_id: Mapped[int] = mapped_column(ForeignKey("actuators.id"), index=True)
    flight_id: Mapped[int] = mapped_column(ForeignKey("flights.id"), index=True)
    model_version_id: Mapped[int | None] = mapped_column(ForeignKey("model_versions.id"))
    flight_index: Mapped[int] = mapped_column(Integer)
    started_at: Mapped[datetime | None] = mapped_column(UTCDateTime)
    features: Mapped[dict[str, Any]] = mapped_column(JSON, default=dict)
    scores: Mapped[dict[str, Any]] = mapped_column(JSON, default=dict)
    confidence: Mapped[float] = mapped_column(Float, default=0.0)
    alarm: Mapped[bool] = mapped_column(default=False)
    class_probabilities: Mapped[dict[str, float] | None] = mapped_column(JSON)
    created_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utcnow)


class ActuatorState(Base):
    """Detection and prognosis state carried from flight to flight (JSON), one row per actuator."""

    __tablename__ = "actuator_states"

    actuator_id: Mapped[int] = mapped_column(ForeignKey("actuators.id"), primary_key=True)
    last_flight_id: Mapped[int | None] = mapped_column(ForeignKey("flights.id"))
    flights_seen: Mapped[int] = mapped_column(Integer, default=0)
    detection: Mapped[dict[str, Any]] = mapped_column(JSON, default=dict)
    fault_mode: Mapped[str | None] = mapped_column(String(16))
    prognosis: Mapped[dict[str, Any] | None] = mapped_column(JSON)
    updated_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utcnow, onupdate=utcnow)


class Alarm(Base):
    """A detected fault on an actuator: open -> acknowledged -> closed, with who, when, note."""

    __tablename__ = "alarms"
    __table_args__ = (UniqueConstraint("actuator_id", "flight_id",
                                       name="uq_alarms_actuator_flight"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    actuator_id: Mapped[int] = mapped_column(ForeignKey("actuators.id"), index=True)
    flight_id: Mapped[int] = mapped_column(ForeignKey("flights.id"))
    status: Mapped[AlarmStatus] = mapped_column(status_type(AlarmStatus), default=AlarmStatus.OPEN,
                                                index=True)
    confidence: Mapped[float] = mapped_column(Float)
    #: the leading class now (it follows the evidence while the alarm is not closed)
    fault_mode: Mapped[str | None] = mapped_column(String(16))
    #: the leading class when the alarm was raised (never rewritten; later changes are
    #: :class:`AlarmEvent` rows)
    raised_fault_mode: Mapped[str | None] = mapped_column(String(16),
                                                          default=_class_at_insert)
    class_probability: Mapped[float | None] = mapped_column(Float)
    #: the class once the evidence confirmed it (server.phm.classification.confirmation);
    #: null while it is provisional
    confirmed_fault_mode: Mapped[str | None] = mapped_column(String(16))
    features: Mapped[list[str]] = mapped_column(JSON, default=list)
    #: the units the alarm may belong to, position -> probability (the ambiguity group: both
    #: winglet drives when it rests on a pair-coupled feature alone); null on alarms raised
    #: before it was recorded
    isolation: Mapped[dict[str, float] | None] = mapped_column(JSON)
    #: the modes present on the unit, the leading one first: ``{mode, probability (its own),
    #: rul_median_flights}`` each (server.phm.classification.modes); null on alarms raised
    #: before it was recorded
    modes: Mapped[list[dict[str, Any]] | None] = mapped_column(JSON)
    rul_median_flights: Mapped[float | None] = mapped_column(Float)
    #: the 5 % quantile of the latest RUL distribution [flights]: what urgency is read from
    rul_low_flights: Mapped[float | None] = mapped_column(Float)
    created_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utcnow)
    acknowledged_by: Mapped[str | None] = mapped_column(String(128))
    acknowledged_at: Mapped[datetime | None] = mapped_column(UTCDateTime)
    closed_by: Mapped[str | None] = mapped_column(String(128))
    closed_at: Mapped[datetime | None] = mapped_column(UTCDateTime)
    note: Mapped[str | None] = mapped_column(Text)
    resolution: Mapped[str | None] = mapped_column(String(16))
    #: a deferral holds until the actuator has seen this many flights, or until this time
    deferred_until_flight: Mapped[int | None] = mapped_column(Integer)
    deferred_until: Mapped[datetime | None] = mapped_column(UTCDateTime)


#: what can happen to an alarm after it was raised, each recorded as its own row:
#: ``class_change``: the leading fault class changed (``from_mode`` -> ``to_mode``);
#: ``confirmed``: the evidence confirmed the class (``to_mode``)
ALARM_EVENT_KINDS = ("class_change", "confirmed")


class AlarmEvent(Base):
    """Something that happened to an alarm after it was raised, on the flight that said so
    (the alarm's timeline): its leading class changing, for one."""

    __tablename__ = "alarm_events"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    alarm_id: Mapped[int] = mapped_column(ForeignKey("alarms.id"), index=True)
    flight_id: Mapped[int | None] = mapped_column(ForeignKey("flights.id"))
    flight_index: Mapped[int | None] = mapped_column(Integer)
    kind: Mapped[str] = mapped_column(String(16))
    from_mode: Mapped[str | None] = mapped_column(String(16))
    to_mode: Mapped[str | None] = mapped_column(String(16))
    created_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utcnow)


class MaintenanceAction(Base):
    """One maintenance action on an actuator (the audit trail): who, when, the work order.

    ``replace``: the unit was removed and ``new_actuator_id`` installed; ``inspect``: no fault
    found, the alarm closed as a false alarm; ``defer``: the alarm held until a flight count or
    a date, with a reason."""

    __tablename__ = "maintenance_actions"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    actuator_id: Mapped[int] = mapped_column(ForeignKey("actuators.id"), index=True)
    alarm_id: Mapped[int | None] = mapped_column(ForeignKey("alarms.id"))
    kind: Mapped[str] = mapped_column(String(16))
    work_order: Mapped[str] = mapped_column(String(32), index=True)
    performed_by: Mapped[str] = mapped_column(String(128))
    key_id: Mapped[int | None] = mapped_column(ForeignKey("api_keys.id"))
    performed_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utcnow)
    note: Mapped[str | None] = mapped_column(Text)
    new_actuator_id: Mapped[int | None] = mapped_column(ForeignKey("actuators.id"))
    new_serial: Mapped[str | None] = mapped_column(String(64))
    closed_alarms: Mapped[int] = mapped_column(Integer, default=0)
    defer_until_flight: Mapped[int | None] = mapped_column(Integer)
    defer_until: Mapped[datetime | None] = mapped_column(UTCDateTime)


class Prognosis(Base):
    """One RUL prediction for an actuator after a flight (the points of the RUL cone);
    ``distribution`` is the filter's :meth:`RulDistribution.to_dict` document as it is."""

    __tablename__ = "prognoses"
    __table_args__ = (UniqueConstraint("actuator_id", "flight_id",
                                       name="uq_prognoses_actuator_flight"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    actuator_id: Mapped[int] = mapped_column(ForeignKey("actuators.id"), index=True)
    flight_id: Mapped[int] = mapped_column(ForeignKey("flights.id"))
    flight_index: Mapped[int] = mapped_column(Integer)
    fault_mode: Mapped[str] = mapped_column(String(16))
    distribution: Mapped[dict[str, Any]] = mapped_column(JSON)
    created_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utcnow)


class StationItem:
    """What every test-station item has (server/services/station.py): the aircraft it is
    scheduled on from ``onset_flight``, its state, who made it and when it ended."""

    id: Mapped[int] = mapped_column(Integer, primary_key=True, sort_order=-2)
    aircraft_id: Mapped[int] = mapped_column(ForeignKey("aircraft.id"), index=True,
                                             sort_order=-1)
    onset_flight: Mapped[int] = mapped_column(Integer)
    status: Mapped[StationStatus] = mapped_column(status_type(StationStatus),
                                                  default=StationStatus.PENDING)
    created_by: Mapped[str] = mapped_column(String(128))
    created_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utcnow)
    cancelled_at: Mapped[datetime | None] = mapped_column(UTCDateTime)


class FlightTruth:
    """What every test-station truth row has: the simulated flight it is of (never in the
    flight log)."""

    id: Mapped[int] = mapped_column(Integer, primary_key=True, sort_order=-1)
    flight_code: Mapped[str] = mapped_column(String(64))
    flight_number: Mapped[int] = mapped_column(Integer)
    created_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utcnow)


class Injection(StationItem, Base):
    """A fault injected by a test-station operator into a simulated aircraft's actuator."""

    __tablename__ = "injections"
    # concurrent faults: one live injection per mode of each actuator
    __table_args__ = (_one_live("injections", "aircraft_id", "position", "fault_mode"),)

    position: Mapped[str] = mapped_column(String(8))
    fault_mode: Mapped[str] = mapped_column(String(16))
    time_to_failure_flights: Mapped[int | None] = mapped_column(Integer)
    severity: Mapped[float | None] = mapped_column(Float)
    failure_flight: Mapped[int | None] = mapped_column(Integer)
    #: progressive faults: the flight the sim worker steers the fault to fail at
    planned_failure_flight: Mapped[int | None] = mapped_column(Integer)


class GroundTruth(FlightTruth, Base):
    """True fault state of a simulated flight, reported by the sim worker."""

    __tablename__ = "ground_truth"
    __table_args__ = (UniqueConstraint("injection_id", "flight_code",
                                       name="uq_ground_truth_injection_flight"),)

    injection_id: Mapped[int] = mapped_column(ForeignKey("injections.id"), index=True)
    severity: Mapped[float] = mapped_column(Float)
    severity_norm: Mapped[float] = mapped_column(Float)
    true_rul_flights: Mapped[int | None] = mapped_column(Integer)


class SensorInjection(StationItem, Base):
    """A degraded sensor injected by a test-station operator into a simulated actuator: the
    simulator flies it in the loop (the controller sees the degraded reading). A separate table
    from :class:`Injection`: a sensor is not a fault mode, has no failure threshold or RUL, and
    may be live beside an actuator fault (one per actuator sensor at a time)."""

    __tablename__ = "sensor_injections"
    __table_args__ = (_one_live("sensor_injections", "aircraft_id", "position", "sensor"),)

    position: Mapped[str] = mapped_column(String(8))
    sensor: Mapped[str] = mapped_column(String(16))
    kind: Mapped[str] = mapped_column(String(16))
    #: noise: factor; drift: metres per flight; quantisation: step in the sensor's unit
    value: Mapped[float] = mapped_column(Float)
    #: the first flight the simulator flew it on (a drift counts its flights from there)
    started_flight: Mapped[int | None] = mapped_column(Integer)


class SensorGroundTruth(FlightTruth, Base):
    """What a sensor injection did to one simulated flight: the noise factor, the LVDT offset
    added [m] or the quantisation step applied."""

    __tablename__ = "sensor_ground_truth"
    __table_args__ = (UniqueConstraint("sensor_injection_id", "flight_code",
                                       name="uq_sensor_ground_truth_injection_flight"),)

    sensor_injection_id: Mapped[int] = mapped_column(ForeignKey("sensor_injections.id"),
                                                     index=True)
    applied: Mapped[float] = mapped_column(Float)


class SimCondition(StationItem, Base):
    """A simulation condition a test-station operator sets on an aircraft, from a flight on
    until cancelled: the air hotter or colder, the hinge loads or the commands larger, or the
    aircraft flying from another base (server.vocabulary.CONDITION_KINDS). Its own table: it
    acts on the whole aircraft, not on an actuator, and one of each kind is live at a time."""

    __tablename__ = "sim_conditions"
    __table_args__ = (_one_live("sim_conditions", "aircraft_id", "kind"),)

    kind: Mapped[str] = mapped_column(String(16))
    #: ambient_offset: K; load_scale, command_scale: factor; load_offset: N per actuator;
    #: None for a base
    value: Mapped[float | None] = mapped_column(Float)
    #: the base flown from (kind base only)
    base: Mapped[str | None] = mapped_column(String(64))
    started_flight: Mapped[int | None] = mapped_column(Integer)


class ConditionGroundTruth(FlightTruth, Base):
    """What a condition did to one simulated flight: the value flown, or for a base the
    flight's ground temperature drawn from its climate [degC]."""

    __tablename__ = "condition_ground_truth"
    __table_args__ = (UniqueConstraint("condition_id", "flight_code",
                                       name="uq_condition_ground_truth_condition_flight"),)

    condition_id: Mapped[int] = mapped_column(ForeignKey("sim_conditions.id"), index=True)
    applied: Mapped[float] = mapped_column(Float)


# ---------------------------------------------------------------------------------------------
# the workers' own telemetry, read by the API's /metrics (server/services/telemetry.py): in the
# database because workers run as other processes, possibly on other hosts
# ---------------------------------------------------------------------------------------------

class WorkerHeartbeat(Base):
    """One running worker process: its last sign of life and the job it holds. A worker that
    stops cleanly removes its row; one that died keeps it, its ``beat_at`` ageing."""

    __tablename__ = "worker_heartbeats"

    worker_id: Mapped[str] = mapped_column(String(128), primary_key=True)
    host: Mapped[str] = mapped_column(String(255))
    pid: Mapped[int] = mapped_column(Integer)
    started_at: Mapped[datetime] = mapped_column(UTCDateTime)
    beat_at: Mapped[datetime] = mapped_column(UTCDateTime)
    #: the job it runs now (None: idle)
    job_id: Mapped[int | None] = mapped_column(Integer)


class JobTiming(Base):
    """One bucket of a job-duration histogram: how many finished jobs of ``kind`` spent, in
    ``stage`` (``job``: the whole attempt), more than the next lower bound and at most ``le``
    seconds, and their seconds summed. Buckets are not cumulative here; /metrics adds them up."""

    __tablename__ = "job_timings"

    kind: Mapped[str] = mapped_column(String(32), primary_key=True)
    stage: Mapped[str] = mapped_column(String(32), primary_key=True)
    #: the bucket's upper bound as text ("0.25", "+Inf")
    le: Mapped[str] = mapped_column(String(24), primary_key=True)
    observations: Mapped[int] = mapped_column(BigInteger)
    seconds: Mapped[float] = mapped_column(Float)


class JobAttempts(Base):
    """How many attempts of jobs of ``kind`` ended with ``outcome`` (done, retried, dead,
    deferred, abandoned), counted by the workers."""

    __tablename__ = "job_attempts"

    kind: Mapped[str] = mapped_column(String(32), primary_key=True)
    outcome: Mapped[str] = mapped_column(String(16), primary_key=True)
    attempts: Mapped[int] = mapped_column(BigInteger)
