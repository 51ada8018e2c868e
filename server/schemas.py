"""Request and response schemas of the REST API (pydantic); never the ORM rows themselves.

Numbers in request bodies are JSON numbers, never ``true`` or a string (``JsonInteger``,
``Number``): an integer field takes a number without a fraction (``174`` or ``174.0``, one JSON
number), a number field any finite number (``Infinity`` has no JSON to read back as). Row ids in
paths and queries are bounded by their column (``IdPath``, ``IdQuery``); text ids follow the
flight-log contract's rule (``ID_PATTERN``).
"""

from __future__ import annotations

import re
from datetime import datetime
from enum import StrEnum
from typing import Annotated, Any, Generic, Literal, TypeVar

from fastapi import Path, Query
from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    ValidationInfo,
    ValidatorFunctionWrapHandler,
    WrapValidator,
    field_validator,
    model_validator,
)
from pydantic_core import PydanticCustomError

from server.flightlog import ID_PATTERN, MAX_ID_LEN
from server.models import ROLES
from server.vocabulary import (
    ABRUPT,
    BASES,
    CONDITION_KINDS,
    FAULT_MODES,
    POSITIONS,
    SENSORS,
    AlarmStatus,
    FlightStatus,
    JobStatus,
    ModelVersionStatus,
    StationStatus,
)

__all__ = [
    "Position",
    "FaultMode",
    "InjectionCreate",
    "ConditionCreate",
    "Role",
    "AircraftCreate",
    "AircraftRead",
    "ActuatorRead",
    "ActuatorReplace",
    "ActuatorInspect",
    "ActuatorDefer",
    "MaintenanceActionRead",
    "WorkOrder",
    "WORK_ORDER_FORM_PATTERN",
    "WORK_ORDER_PATTERN",
    "FlightRead",
    "FlightAccepted",
    "SignalsRead",
    "KeyCreate",
    "KeyRead",
    "KeyCreated",
    "Page",
    "Identifier",
    "JsonInteger",
    "Number",
    "IdPath",
    "IdQuery",
    "MAX_INT32",
    "FlightNumber",
    "Offset",
    "FlightStatusFilter",
    "JobStatusFilter",
    "AlarmStatusFilter",
]

# Literal over the vocabulary's tuples: Pydantic reads them at run time, mypy wants the values
# written out (repeating them would make two owners of the vocabulary)
Position = Literal[POSITIONS]  # type: ignore[valid-type]
Role = Literal[ROLES]  # type: ignore[valid-type]  # as Position
#: tails, flight codes, serials: ASCII letters, digits, '.', '_', '-', 1-64, not only dots
Identifier = Annotated[str, Field(pattern=ID_PATTERN, max_length=MAX_ID_LEN)]

#: a work-order reference: letters, digits and '-' '/' '_', 3-32, starting with a letter or
#: digit (``WO-2026-0042``, ``AMM/27-51/113``)
#: the form's ``pattern`` attribute uses the same text (escaped for the browser's v-flag
#: regular expressions, which refuse a bare '/' or '-' in a class)
WORK_ORDER_FORM_PATTERN = r"[A-Za-z0-9][A-Za-z0-9\/_\-]{2,31}"
WORK_ORDER_PATTERN = f"^{WORK_ORDER_FORM_PATTERN}$"
WorkOrder = Annotated[str, Field(pattern=WORK_ORDER_PATTERN, min_length=3, max_length=32,
                                 description="Work-order reference, e.g. WO-2026-0042.")]

#: PostgreSQL's INTEGER, the type of the id, flight-number and count columns: no request number
#: beyond it reaches the database (SQLite would store it, PostgreSQL refuses it)
MAX_INT32 = 2**31 - 1


def _json_integer(value: Any, handler: ValidatorFunctionWrapHandler,
                  info: ValidationInfo) -> Any:
    # JSON has one number type and JSON Schema's "integer" holds 174.0 as well as 174, so
    # both are taken; true and "174" (which lax parsing would take) are no integer. A
    # dashboard form's fields are text, validated in pydantic's strings mode: parsed as such
    if info.mode != "string":
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise PydanticCustomError("int_type", "Input should be a valid integer")
        if isinstance(value, float) and value.is_integer():
            value = int(value)  # 1e300 then meets the field's bound, not a parsing error
    return handler(value)  # a fraction, infinity or NaN: refused by int itself


#: what makes an ``int`` of a request body take 174 or 174.0 and refuse true or "174": after
#: the field's bounds, ``Annotated[int, Field(ge=0, le=9), JsonInteger]`` (bounds after a
#: validator come out of pydantic's JSON schema as "ge"/"le", not minimum/maximum)
JsonInteger = WrapValidator(_json_integer)
#: a number of a request body (bounds on each field): any finite JSON number, an integer too;
#: never true or "1.5" (pydantic's strict float, which takes ints)
Number = Annotated[float, Field(strict=True, allow_inf_nan=False)]
#: a row id (aircraft's actuator, flight, job, key, model, alarm, test-station item) in a path
#: or a query: within its INTEGER column, so that no larger one reaches the database driver
IdPath = Annotated[int, Path(ge=1, le=MAX_INT32)]
IdQuery = Annotated[int | None, Query(ge=1, le=MAX_INT32)]
#: an aircraft's flight number (its n-th flight)
FlightNumber = Annotated[int, Field(ge=0, le=MAX_INT32), JsonInteger]
#: the offset of a listed page
Offset = Annotated[int, Query(ge=0, le=MAX_INT32)]


def one_of(states: type[StrEnum]) -> str:
    """The regular expression of exactly ``states``' values: a query parameter checked by
    ``pattern`` (its 422 and its OpenAPI text as before) while the enum stays the one list."""
    return "^(" + "|".join(re.escape(s.value) for s in states) + ")$"


#: the ``status`` filters of the flight and job lists
FlightStatusFilter = Annotated[str | None, Query(pattern=one_of(FlightStatus))]
JobStatusFilter = Annotated[str | None, Query(pattern=one_of(JobStatus))]
#: the ``status`` filter of the alarm inbox
AlarmStatusFilter = Annotated[str | None, Query(pattern=one_of(AlarmStatus))]

T = TypeVar("T")


class Page(BaseModel, Generic[T]):
    items: list[T]
    total: int
    limit: int
    offset: int


class ActuatorSerials(BaseModel):
    model_config = ConfigDict(extra="forbid")
    WL1: Identifier
    WL2: Identifier
    WT: Identifier


class AircraftCreate(BaseModel):
    model_config = ConfigDict(extra="forbid")
    tail: Identifier = Field(description="Tail id, unique in the fleet.")
    base: str = Field(min_length=1, max_length=64, description="Home base, e.g. Turin.")
    actuators: ActuatorSerials

    @field_validator("actuators")
    @classmethod
    def _distinct(cls, value: ActuatorSerials) -> ActuatorSerials:
        if len({value.WL1, value.WL2, value.WT}) != 3:
            raise ValueError("the three actuator serials must differ")
        return value


class ActuatorRead(BaseModel):
    model_config = ConfigDict(from_attributes=True)
    id: int
    aircraft_tail: str
    position: Position
    serial: str
    installed_at: datetime
    removed_at: datetime | None
    removal_note: str | None
    failed_at_flight: int | None = Field(None, description=(
        "The aircraft flight at which this unit reached failure (it stays failed until "
        "replaced); null when it has not failed."))
    failed_at: datetime | None = None


class AircraftRead(BaseModel):
    tail: str
    base: str
    created_at: datetime
    actuators: dict[str, ActuatorRead] = Field(description="Installed actuators by position.")


class ActuatorReplace(BaseModel):
    model_config = ConfigDict(extra="forbid")
    new_serial: Identifier
    work_order: WorkOrder
    note: str | None = Field(None, max_length=2000)


class ActuatorInspect(BaseModel):
    """Inspection found no fault: the unit's alarms close as false alarms."""

    model_config = ConfigDict(extra="forbid")
    work_order: WorkOrder
    note: str | None = Field(None, max_length=2000)


class ActuatorDefer(BaseModel):
    """Defer the unit's open alarm for ``flights`` more flights or until ``until`` (or both:
    whichever comes first)."""

    model_config = ConfigDict(extra="forbid")
    work_order: WorkOrder
    reason: str = Field(min_length=3, max_length=2000)
    flights: Annotated[int, Field(ge=1, le=1000), JsonInteger] | None = None
    until: datetime | None = Field(None, description="An aware date-time (with its zone).")

    @model_validator(mode="after")
    def _bounded(self) -> ActuatorDefer:
        if self.flights is None and self.until is None:
            raise ValueError("give flights or until (or both)")
        if self.until is not None and self.until.tzinfo is None:
            raise ValueError("until needs a time zone (e.g. 2027-01-31T00:00:00Z)")
        return self


class MaintenanceActionRead(BaseModel):
    model_config = ConfigDict(from_attributes=True)
    id: int
    actuator_id: int
    kind: Literal["replace", "inspect", "defer"]
    work_order: str
    performed_by: str = Field(description="The name of the key that recorded the action.")
    performed_at: datetime
    note: str | None
    alarm_id: int | None
    closed_alarms: int
    new_actuator_id: int | None
    new_serial: str | None
    defer_until_flight: int | None = Field(description=(
        "Defer: the deferral ends when the unit has been analysed on this many flights."))
    defer_until: datetime | None


class FlightRead(BaseModel):
    id: int
    aircraft: str | None
    flight: str | None
    status: str
    reasons: list[dict[str, Any]]
    sha256: str
    size_bytes: int
    content_kind: str
    started_at: datetime | None
    block_hours: float | None
    received_at: datetime
    uploader: str | None
    status_url: str


class FlightAccepted(BaseModel):
    id: int
    status: str
    status_url: str
    duplicate: bool = Field(description=(
        "True when this upload (the same bytes and, for CSV/MAT, the same metadata fields) "
        "is an accepted flight already; nothing new was registered. A rejected flight's "
        "upload is evaluated again."))


class SignalsRead(BaseModel):
    flight_id: int
    decimation: int = Field(description="Every n-th 800 Hz sample is returned.")
    t: list[float]
    channels: dict[str, list[float]]


class KeyCreate(BaseModel):
    model_config = ConfigDict(extra="forbid")
    name: str = Field(min_length=1, max_length=128)
    role: Role


class KeyRead(BaseModel):
    model_config = ConfigDict(from_attributes=True)
    id: int
    name: str
    role: str
    prefix: str
    created_at: datetime
    revoked_at: datetime | None


class KeyCreated(KeyRead):
    key: str = Field(description="The key itself; shown only now.")


# ---------------------------------------------------------------------------------------------
# Test station (the API's and the dashboard's form share it)
# ---------------------------------------------------------------------------------------------

FaultMode = Annotated[str, Field(pattern="^(" + "|".join(FAULT_MODES) + ")$")]


class InjectionCreate(BaseModel):
    model_config = ConfigDict(extra="forbid")
    aircraft: Identifier
    position: Position
    fault_mode: FaultMode
    onset_flight: Annotated[int, Field(ge=0, le=100_000), JsonInteger] = Field(
        0, description="Aircraft flight number at which the fault appears; 0 = the next flight.")
    time_to_failure_flights: Annotated[int, Field(ge=10, le=5000), JsonInteger] | None = Field(
        None, description="Progressive modes: flights from onset to failure (sets the "
        "progression rate); default: drawn by the simulator's law.")
    severity: Number | None = Field(None, ge=0.01, le=1.0, description=(
        "SE/BDO: imposed severity as a fraction of the failure threshold, 0.01-1 (default "
        "1.0)."))

    @model_validator(mode="after")
    def _severity_only_a_priori(self) -> InjectionCreate:
        if self.severity is not None and self.fault_mode not in ABRUPT:
            raise ValueError("severity is imposed only for SE and BDO; progressive faults "
                             "start at onset and grow")
        return self


#: what a sensor injection does; ``value``: the noise factor, the LVDT offset added each flight
#: [m per flight], or the coarser quantisation step in the sensor's unit (A, V, rad, m)
SENSOR_INJECTION_KINDS: tuple[str, ...] = ("noise", "drift", "quantisation", "stuck", "clipped")
#: the converters' full scales (sim_worker.params.SensorParams): a stuck value lies within
#: +-range, a clip level within (0, range]
SENSOR_RANGE = {"current": 64.0, "voltage": 512.0}
#: a stuck or clipped LVDT opens the position loop: the motor drives the rod on, and without
#: the rod's end stops (not modelled) the simulator flies it metres beyond its stroke (a stuck
#: WT LVDT: 4.8 m of travel on a 15 s flight), so both are refused. A stuck resolver freezes
#: the commutation angle: the drive loses its torque control but the rod stays within its
#: stroke (12 mm at most on the same flight), so it is flown; a resolver's angle wraps, it
#: never saturates, so a clipped one is no resolver failure and is refused
CLAMPED_SENSORS = tuple(SENSOR_RANGE)
#: a stuck resolver reads one shaft angle [rad], within a turn
STUCK_RESOLVER_RANGE = 3.141592653589793
#: the coarsest step an operator may ask per sensor: far beyond what a sensor finding needs,
#: short of a reading that no longer closes the loop (a 1 mm LVDT step on a +-62 mm stroke)
MAX_STEP = {"current": 4.0, "voltage": 50.0, "resolver": 0.1, "lvdt": 1e-3}
MAX_NOISE_FACTOR = 50.0
MAX_DRIFT_M_PER_FLIGHT = 1e-3


#: a sensor injection's or a condition's start: it lasts until cancelled
UntilCancelledOnset = Annotated[int, Field(
    ge=0, le=100_000, description="Aircraft flight number it starts at; 0 = the next flight. "
    "It lasts until cancelled."), JsonInteger]


class CheckedSpec(BaseModel):
    """A station item's create body whose values its kind's rule checks together
    (:meth:`problem`: why they are refused, None when they are fine)."""

    model_config = ConfigDict(extra="forbid")
    aircraft: Identifier

    def problem(self) -> str | None:
        return None

    @model_validator(mode="after")
    def _values_in_bounds(self) -> CheckedSpec:
        problem = self.problem()
        if problem:
            raise ValueError(problem)
        return self


class SensorInjectionCreate(CheckedSpec):
    position: Position
    sensor: Literal[SENSORS] = Field(  # type: ignore[valid-type]  # as Position
        description="current (channels ia ib ic) | voltage (va vb vc) | resolver (theta) | "
        "lvdt (x): the sensor names a sensor finding carries")
    kind: Literal[SENSOR_INJECTION_KINDS] = Field(  # type: ignore[valid-type]  # as Position
        description="noise: rms noise x value; drift (LVDT only): offset + value metres per "
        "flight; quantisation: readings rounded to a step of value (A, V, rad, m)")
    value: Number = Field(description=(
        f"noise: factor, above 1 and at most {MAX_NOISE_FACTOR:g}; drift: metres per flight, "
        f"non-zero, |value| <= {MAX_DRIFT_M_PER_FLIGHT:g}; quantisation: step, above the "
        "sensor's own step, at most " + ", ".join(f"{v:g} ({k})" for k, v in MAX_STEP.items())
        + "; stuck (current, voltage): the reading, within the converter's range (64 A, "
        "512 V); stuck (resolver): the shaft angle, within +-pi rad; clipped (current, "
        "voltage): the level, above 0, within that range"))
    onset_flight: UntilCancelledOnset = 0

    def problem(self) -> str | None:
        return sensor_value_problem(self.sensor, self.kind, self.value)


def sensor_value_problem(sensor: str, kind: str, value: float) -> str | None:
    """Why ``value`` is out of bounds for this sensor and kind; None when it is fine."""
    if kind == "noise" and not 1.0 < value <= MAX_NOISE_FACTOR:
        return f"noise factor must be above 1 and at most {MAX_NOISE_FACTOR:g}"
    if kind == "drift":
        if sensor != "lvdt":
            return "drift is an LVDT fault (its offset against the rod); use sensor lvdt"
        if value == 0 or abs(value) > MAX_DRIFT_M_PER_FLIGHT:
            return (f"drift must be non-zero and at most {MAX_DRIFT_M_PER_FLIGHT:g} m per "
                    "flight in size")
    if kind in ("stuck", "clipped"):
        return _clamp_problem(sensor, kind, value)
    if kind == "quantisation":
        native = NATIVE_STEP[sensor]
        if not native < value <= MAX_STEP[sensor]:
            return (f"a {sensor} quantisation step must be above its own step ({native:.3g}) "
                    f"and at most {MAX_STEP[sensor]:g}")
    return None


def _clamp_problem(sensor: str, kind: str, value: float) -> str | None:
    if sensor == "resolver" and kind == "stuck":
        if not -STUCK_RESOLVER_RANGE <= value <= STUCK_RESOLVER_RANGE:
            return "a stuck resolver reads one shaft angle, within +-pi rad"
        return None
    if sensor == "resolver":
        return ("a resolver's angle wraps, it never saturates: clipped is no resolver failure "
                "(stuck is offered)")
    if sensor not in CLAMPED_SENSORS:
        return (f"a {kind} LVDT opens the position loop: without the rod's end stops, which "
                "the simulator does not model, the rod would run metres beyond its 30 mm "
                "stroke; stuck and clipped are offered for the current, voltage and (stuck) "
                "resolver sensors")
    full = SENSOR_RANGE[sensor]
    if kind == "stuck" and not -full <= value <= full:
        return f"a stuck {sensor} reading lies within +-{full:g}"
    if kind == "clipped" and not 0 < value <= full:
        return f"a {sensor} clip level lies above 0 and at most {full:g}"
    return None


#: the simulated sensors' own steps (sim_worker.params.SensorParams; the API does not import
#: the simulator, a test keeps the two equal): a coarser step must be coarser than these
NATIVE_STEP = {"current": 2.0**-5, "voltage": 2.0**-3, "resolver": 2.0 * 3.141592653589793 / 65536,
               "lvdt": 2.0**-19}


#: a condition's bounds: (low, high) of its value, per kind. Ambient: +-30 K spans the air of
#: the hottest and coldest days around a base's monthly mean (the climates' spread is 2-6 K);
#: scales: above 0 (a negative scale would flip the load or the command) and at most 3 (eq. 1
#: draws sigma_F and sigma_x at 1 +- 0.3, truncated at 3 sigma: at most 1.9); load offset: one
#: nominal winglet load (1000 N, ten times eq. 1's sigma_F0 spread) either way
CONDITION_BOUNDS: dict[str, tuple[float, float]] = {
    "ambient_offset": (-30.0, 30.0), "load_scale": (0.0, 3.0), "load_offset": (-1000.0, 1000.0),
    "command_scale": (0.0, 3.0)}
#: kinds whose low bound is excluded (a scale of 0 is no load or no motion, not a condition)
_OPEN_LOW = ("load_scale", "command_scale")
#: the unit of a condition's value (the scales are factors, without one)
CONDITION_UNITS = {"ambient_offset": "K", "load_offset": "N"}


def condition_range(kind: str) -> str:
    """A condition kind's bounds in words, e.g. ``above 0 and at most 3``: the schema's
    description, its error message and the dashboard's hint say the same."""
    low, high = CONDITION_BOUNDS[kind]
    unit = f" {CONDITION_UNITS[kind]}" if kind in CONDITION_UNITS else ""
    side = "above" if kind in _OPEN_LOW else "at least"
    return f"{side} {low:g}{unit} and at most {high:g}{unit}"


class ConditionCreate(CheckedSpec):
    kind: Literal[CONDITION_KINDS] = Field(  # type: ignore[valid-type]
        description="ambient_offset: K added to the air temperature, ground to cruise; "
        "load_scale: the hinge load's scale (eq. 1 sigma_F, multiplied); load_offset: N added "
        "to every actuator's hinge load (eq. 1 sigma_F0); command_scale: the commanded "
        "motion's scale (eq. 1 sigma_x, multiplied); base: fly from that base's climate")
    value: Number | None = Field(None, description="; ".join(
        f"{kind} {condition_range(kind)}" for kind in CONDITION_BOUNDS) + "; none for a base")
    base: str | None = Field(None, description="kind base only: one of " + ", ".join(BASES))
    onset_flight: UntilCancelledOnset = 0

    def problem(self) -> str | None:
        return condition_problem(self.kind, self.value, self.base)


def condition_problem(kind: str, value: float | None, base: str | None) -> str | None:
    """Why a condition is malformed or out of bounds; None when it is fine."""
    if kind == "base":
        if value is not None:
            return "a base condition takes a base, not a value"
        if base not in BASES:
            return f"base must be one of {', '.join(BASES)}"
        return None
    if base is not None:
        return f"a {kind} condition takes a value, not a base"
    if value is None:
        return f"a {kind} condition needs a value"
    low, high = CONDITION_BOUNDS[kind]
    inside = (low < value if kind in _OPEN_LOW else low <= value) and value <= high
    return None if inside else f"{kind} must be {condition_range(kind)}"


# the test station's bodies and read models of the API (server/api/test_station.py)

MAX_SEVERITY = 10.0  # ground truth: severity and severity_norm (see GroundTruthIn)


class InjectionRead(BaseModel):
    id: int
    aircraft: str
    position: str
    fault_mode: str
    onset_flight: int
    time_to_failure_flights: int | None
    severity: float | None
    status: StationStatus
    created_by: str
    created_at: datetime
    cancelled_at: datetime | None
    failure_flight: int | None
    planned_failure_flight: int | None = Field(
        None, description="Progressive faults: the flight the simulator steers the fault to "
        "fail at (its start plus the requested or drawn time to failure).")
    warnings: list[str] = Field(default_factory=list, description=(
        "What the operator should know, e.g. a time to failure outside the spans the active "
        "model was trained on."))


class InjectionStatus(BaseModel):
    model_config = ConfigDict(extra="forbid")
    status: Annotated[str, Field(pattern="^(active|failed)$")]
    failure_flight: FlightNumber | None = None
    planned_failure_flight: FlightNumber | None = None


class FlightRef(BaseModel):
    """The simulated flight a ground truth is of."""

    model_config = ConfigDict(extra="forbid")
    flight: Identifier
    flight_number: FlightNumber


class FaultTruth(BaseModel):
    """A fault injection's true state on one flight."""

    model_config = ConfigDict(extra="forbid")
    # the fault's size in its own unit (m, ohm, ...; every failure threshold is at most 1), and
    # as a fraction of the threshold: a fault is failed at 1, reported a little beyond at most
    severity: Number = Field(ge=0, le=MAX_SEVERITY)
    severity_norm: Number = Field(ge=0, le=MAX_SEVERITY)
    true_rul_flights: FlightNumber | None = None


class AppliedTruth(BaseModel):
    """What a sensor injection or a condition did to one flight."""

    model_config = ConfigDict(extra="forbid")
    applied: Number = Field(ge=-1e6, le=1e6, description=(
        "sensor injection: the noise factor, the LVDT offset added [m] or the quantisation "
        "step; condition: the value flown (K, factor, N), or for a base the flight's ground "
        "temperature drawn from its climate [degC]"))


class GroundTruthIn(FaultTruth, FlightRef):
    pass


class GroundTruthRead(GroundTruthIn):
    model_config = ConfigDict(extra="ignore")
    injection_id: int


class AppliedTruthIn(AppliedTruth, FlightRef):
    pass


class SensorTruthRead(AppliedTruthIn):
    model_config = ConfigDict(extra="ignore")
    sensor_injection_id: int


class ConditionTruthRead(AppliedTruthIn):
    model_config = ConfigDict(extra="ignore")
    condition_id: int


class SensorInjectionRead(BaseModel):
    id: int
    aircraft: str
    position: str
    sensor: str
    channels: list[str] = Field(description='the flight-log channels it degrades, e.g. "WT.x"')
    kind: str
    value: float
    onset_flight: int
    started_flight: int | None
    status: StationStatus
    created_by: str
    created_at: datetime
    cancelled_at: datetime | None


class ConditionRead(BaseModel):
    id: int
    aircraft: str
    kind: str
    value: float | None
    base: str | None
    onset_flight: int
    started_flight: int | None
    status: StationStatus
    created_by: str
    created_at: datetime
    cancelled_at: datetime | None


# what the simulator reports of one flight in one request (PUT /test-station/flights/{flight}):
# per item of the flight plan, its id and its truth on the flight

class FlownItem(BaseModel):
    model_config = ConfigDict(extra="forbid")
    id: Annotated[int, Field(ge=1, le=MAX_INT32), JsonInteger]


class FaultFlown(FaultTruth, FlownItem):
    planned_failure_flight: FlightNumber | None = Field(None, description=(
        "Progressive faults: the flight the simulator steers the fault to fail at (recorded "
        "while the injection is live)."))
    failure_flight: FlightNumber | None = Field(None, description=(
        "The flight from which the drive is failed, when this flight took the fault to its "
        "threshold: the injection becomes failed, its actuator failed, and every flight it "
        "was reported on gets its true RUL."))


class AppliedFlown(AppliedTruth, FlownItem):
    pass


# ---------------------------------------------------------------------------------------------
# GET /api/v1/storage (server/services/storage.py)
# ---------------------------------------------------------------------------------------------

class FlightLogUsage(BaseModel):
    state: Literal["accepted", "rejected", "raw_pruned"] = Field(description=(
        "accepted: a flight with its raw log (any status but rejected); rejected; raw_pruned: "
        "analysed, its log removed by the raw-log retention (0 bytes)."))
    reason: str | None = Field(description=(
        "accepted and raw_pruned: the flight's status; rejected: its first reason's code."))
    flights: int
    bytes: int = Field(description="The bytes of the group's distinct files (a file backing "
                       "several rows counts once).")


class RejectedByKey(BaseModel):
    key_id: int | None
    key_name: str | None
    role: str | None
    flights: int
    bytes: int
    charged_bytes: int = Field(description=(
        "What the key's rejected flights take of its quota: each at least 64 KiB."))
    quota_bytes: int = Field(description="HMSM_REJECTED_BYTES_PER_KEY.")


class BlobStoreUsage(BaseModel):
    files: int
    bytes: int
    referenced_files: int = Field(description="Files a flight row keeping its log refers to.")
    referenced_bytes: int
    unreferenced_files: int = Field(description="Files no such row refers to.")
    unreferenced_bytes: int
    missing_files: int = Field(description="Files such rows refer to that are not on disk.")


class FileUsage(BaseModel):
    kind: Literal["blobs", "temporary_uploads", "campaign", "evaluation_reports", "database",
                  "logs", "other"]
    name: str | None = Field(description="The campaign's name (campaigns are listed one by "
                             "one); null for the other kinds.")
    files: int
    bytes: int


class DirectoryUsage(BaseModel):
    files: int
    bytes: int = Field(description="Every file under HMSM_DATA_DIR: the sum of `files`.")
    free_bytes: int


class DatabaseUsage(BaseModel):
    dialect: str
    bytes: int | None = Field(description="PostgreSQL's database size; null for SQLite, whose "
                              "file is listed under `files` (kind `database`).")


class StorageReport(BaseModel):
    flight_logs: list[FlightLogUsage]
    rejected_by_key: list[RejectedByKey]
    blob_store: BlobStoreUsage
    files: list[FileUsage]
    data_dir: DirectoryUsage
    database: DatabaseUsage


# ---------------------------------------------------------------------------------------------
# GET /api/v1/jobs (the queue: server/jobs)
# ---------------------------------------------------------------------------------------------

class JobRead(BaseModel):
    model_config = ConfigDict(from_attributes=True)
    id: int
    kind: str
    flight_id: int | None
    lock_key: str
    status: str
    attempts: int
    max_attempts: int
    run_after: datetime
    lease_until: datetime | None
    locked_by: str | None
    last_error: str | None
    created_at: datetime
    started_at: datetime | None
    finished_at: datetime | None


# ---------------------------------------------------------------------------------------------
# Actuator health, prognoses, alarms, the fleet grid (server/api/health_records.py)
# ---------------------------------------------------------------------------------------------

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


class RateHypothesisRead(BaseModel):
    """The leading rate hypothesis of a prediction (``RulDistribution.hypothesis``)."""

    name: str = Field(description="fast, medium, slow, ...: the band of fault-to-failure spans")
    spans: str = Field(description="the band in words, e.g. '30-100 flights'")
    weight: float = Field(description="its posterior weight [0, 1]")
    weights: dict[str, float] = Field(description="every hypothesis's weight by name")


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
    hypothesis: RateHypothesisRead | None = Field(
        default=None, description="with a bank of rate hypotheses: the leading one (the "
        "fault's speed the measurements favour) and every hypothesis's weight")


class PrognosisRead(BaseModel):
    model_config = ConfigDict(from_attributes=True)
    flight_id: int
    flight_index: int
    fault_mode: str
    distribution: RulDistributionRead
    created_at: datetime


class ModePresentRead(BaseModel):
    """One mode present on an alarm's unit."""

    mode: str
    probability: float | None = Field(description="its own probability of being present "
                                      "(not competing with the other modes')")
    rul_median_flights: float | None = Field(description="median RUL of its own prognosis "
                                             "(null: a step fault, or none yet)")
    confirmed: bool = Field(default=False, description="confirmed: the leading one as the "
                            "alarm's class, another as present beside it (its own probability, "
                            "or its own feature beyond the leading mode's cross-talk, held on "
                            "consecutive flights); else provisional")
    by_feature: bool = Field(default=False, description="named by its own feature, beyond what "
                             "the leading mode's faults alone gave it in the design, while its "
                             "own probability is below the mode-set threshold")


class AlarmRead(BaseModel):
    id: int
    aircraft: str
    position: str
    actuator_id: int
    flight_id: int
    status: AlarmStatus
    urgency: str | None = Field(description="replace_now | act_within | monitor | deferred; "
                                "the inbox order (server/services/urgency.py; a 5 % RUL "
                                "quantile under 1 flight is replace_now: due now); null once "
                                "the alarm is closed (a closed alarm claims no live urgency)")
    urgency_label: str | None
    act_within_flights: int | None
    confidence: float
    fault_mode: str | None = Field(description="the leading class now (it follows the "
                                   "evidence while the alarm is not closed)")
    raised_fault_mode: str | None = Field(description="the leading class when the alarm was "
                                          "raised; later changes are its events")
    class_probability: float | None
    confirmed_fault_mode: str | None = Field(
        default=None, description="the class once the evidence confirmed it (the leading class "
        "on consecutive flights at a high enough probability); null while it is provisional")
    features: list[str]
    isolation: dict[str, float] | None = Field(
        default=None, description="the units the alarm may belong to, position -> "
        "probability: its own alone, or both winglet drives (an ambiguity group) when it rests "
        "on a feature the partner drive moves too; null on alarms raised before it was kept")
    modes: list[ModePresentRead] | None = Field(
        default=None, description="every mode present on the unit, the leading one first "
        "(two degradations at once: each with its own probability and RUL; the alarm's RUL is "
        "the earliest failure among them); null on alarms raised before it was kept")
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
                      "to_mode on this flight; confirmed: the evidence confirmed the class "
                      "to_mode on this flight, or to_mode present beside it")
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


class OutsideDesignRead(BaseModel):
    """A flight condition far outside the healthy design flights' range: the features that
    model it are not judged on the flight (server/phm/baselines.py)."""

    condition: str = Field(description="one of the conditions the baselines follow "
                           "(CONDITION_NAMES, server/phm/features/results.py), e.g. "
                           "temp_mean_c")
    value: float | None
    low: float | None = Field(description="the design flights' range of the condition")
    high: float | None
    features: list[str]


class SensorFlightRead(BaseModel):
    flight_id: int
    flight_index: int
    started_at: datetime | None
    findings: list[SensorFindingRead]
    set_aside: list[str] = Field(description="features not judged on this flight")
    widened: dict[str, float] = Field(
        description="features judged with a widened flight scatter: added variance [z^2]")
    outside_design: list[OutsideDesignRead] = Field(
        default_factory=list, description="conditions far outside the design's")


class GridCellRead(BaseModel):
    tail: str
    base: str
    position: str
    actuator_id: int
    serial: str
    status: str = Field(description="the urgency's colour: red | amber | yellow | grey | green")
    urgency: str  # replace_now | act_within | monitor | deferred | healthy
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
    outside_design: list[OutsideDesignRead] = Field(
        default_factory=list, description="conditions of the latest analysed flight far "
        "outside the model's design flights: the features they model were not judged")


# ---------------------------------------------------------------------------------------------
# PHM model versions (server/api/models_api.py)
# ---------------------------------------------------------------------------------------------

# No leading dot: "." and ".." would name the campaigns directory or the data directory.
_MODEL_NAME = r"^[A-Za-z0-9_-][A-Za-z0-9._-]{0,63}$"


class ModelRead(BaseModel):
    model_config = ConfigDict(from_attributes=True)
    id: int
    name: str
    status: ModelVersionStatus
    active: bool
    metrics: dict[str, Any]
    training: dict[str, Any]
    error: str | None
    created_at: datetime
    finished_at: datetime | None


class ModelSummary(BaseModel):
    id: int
    name: str
    status: ModelVersionStatus
    active: bool
    accuracy: float | None
    created_at: datetime


class GenerateSpec(BaseModel):
    model_config = ConfigDict(extra="forbid")
    seed: Annotated[int, Field(ge=0, le=MAX_INT32), JsonInteger]
    # quick alone: about 920 flights in 3 minutes on 2 cores, streamed (docs/SECURITY.md);
    # paper (about 8 GB) and protocol (hours) campaigns are for `hmsm campaign` / `protocol`
    scale: Literal["quick"] = Field("quick", description=(
        "Only quick; larger campaigns come from the command line (`hmsm campaign`)."))


class TrainRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")
    campaign: str = Field(pattern=_MODEL_NAME, description=(
        "Design campaign directory name under HMSM_DATA_DIR/campaigns."))
    generate: GenerateSpec | None = Field(None, description=(
        "Simulate the design campaign first if it does not exist yet; it is removed once "
        "training has read it."))
    seed: Annotated[int, Field(ge=0, le=MAX_INT32), JsonInteger] = Field(
        0, description="Seed of the 70/30 split.")
    name: str | None = Field(None, pattern=_MODEL_NAME)
    activate: bool = True


class TrainAccepted(BaseModel):
    model_id: int
    job_id: int
    status_url: str
