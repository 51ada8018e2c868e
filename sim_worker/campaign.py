"""Campaigns: design / verification sets of flight logs plus a manifest with the ground truth.

Layout: ``DIR/manifest.json`` and ``DIR/flights/<tail>/<flight>.parquet``; DIR a local
directory or an S3 prefix ``s3://bucket/prefix`` (``server.campaign_store.CampaignStore``),
which the workers write kept logs to directly: a Dask cluster needs no shared filesystem. The
manifest schema (``ema-campaign/1``) is a contract with the PHM chain; see :func:`run_campaign`.
What becomes of a rendered flight is the campaign's :class:`FlightSink`'s choice: its file
(:class:`ParquetSink`, the default) or, streamed, its features (``server.campaigns.FeatureSink``).

Determinism: every aircraft seed, pattern seed and flight seed derives from the campaign seed via
``numpy.random.SeedSequence`` with a fixed key (kind, aircraft, pattern, flight), never from the
worker that runs it; results are identical for any number of workers or any executor.
Resumable: finished patterns are kept in ``DIR/progress/`` until the manifest is written.

Fault-to-failure runs start with ``lead_flights`` healthy flights (the actuator's service before
the fault, every one rendered), then advance the progression law every flight from the onset;
only every ``render_every``-th flight after the onset (and the failure flight) is simulated at
12 kHz and given to the sink; the others use the quasi-static
:func:`~sim_worker.flight.estimate_summary` of the same flight conditions (which agrees with
the rendered flights on the wear drivers of either role), so a run's expected life does not
depend on ``render_every``.
"""

from __future__ import annotations

import json
import math
import os
from collections import Counter
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import Executor, ProcessPoolExecutor, as_completed
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from server.campaign_store import CampaignStore
from server.flightlog import FlightLog, write_parquet
from server.vocabulary import POSITIONS, SENSORS, WINGLET_PAIR

from .conditions import NO_CONDITIONS, Conditions
from .faults import (
    A_PRIORI,
    ENVELOPE_FLIGHTS,
    MODES,
    PROGRESSIVE,
    SPAN_DRAWS,
    SPAN_FLIGHTS,
    FaultState,
    advance_fault,
    healthy,
    new_fault,
)
from .fleet import BASES, DEFAULT_WINGLET_MODE, FLEET_BASES, Aircraft, WingletMode, build_aircraft
from .flight import (
    estimate_summary,
    flight_start,
    reference_summary,
    simulate_flight,
)

__all__ = ["ScaleConfig", "SCALES", "plan_campaign", "execution_order", "run_campaign",
           "snapshot_campaign", "run_pattern", "FORMAT",
           "SETTINGS_FILE", "FlightSink", "ParquetSink", "PatternTask", "SensorFault",
           "fleet_for"]

FORMAT = "ema-campaign/1"
#: the settings a finished campaign was made with, beside its manifest
SETTINGS_FILE = "campaign_settings.json"
_KIND_CODE = {"design": 1, "verification": 2}
_MAX_FLIGHTS = 2000  # a fault-to-failure run stops here at the latest
_MAX_SPAN = 1500.0  # largest expected span a user may ask for [flights], under _MAX_FLIGHTS


@dataclass(frozen=True)
class ScaleConfig:
    duration_s: float  # s of reference actuator activity per recording
    healthy_patterns: int  # number of healthy patterns (spread over the aircraft)
    #: flights per healthy pattern: a number, or a (low, high) range each pattern draws its
    #: length from (uniform integers, from the pattern's seed): the paper's healthy cycles
    #: ran as long as its degradation patterns (section 5.1)
    healthy_flights: int | tuple[int, int]
    patterns_per_mode: int  # degradation patterns per fault mode
    #: render every k-th flight of a fault-to-failure run; odd, so the rendered flights take
    #: both winglet roles (the active drive alternates by flight: an even step would read a
    #: faulty winglet drive in one role only, never its motor features or never its play)
    render_every: int
    apriori_flights: int  # flights per SE / BDO pattern
    apriori_onset: int  # index of the first faulty flight of an SE / BDO pattern
    #: healthy flights (all rendered) before a progressive fault starts: the actuator's
    #: in-service history after installation, from which detection learns its own reference
    lead_flights: int = 8
    #: range of the expected fault-to-failure span drawn per pattern [flights]
    span_flights: tuple[float, float] = SPAN_FLIGHTS
    #: how a pattern draws its span from ``span_flights``: "uniform", or "log" (log-uniform,
    #: as many runs between 30 and 100 flights as between 300 and 1000: a design campaign
    #: over the test station's whole envelope)
    span_draw: str = "uniform"
    #: recording lengths [s] each rendered flight draws from (uniformly, from the flight's
    #: seed); empty: every flight ``duration_s``. A fleet's recordings vary in length, and a
    #: feature's scatter with them (server.phm.detection: the evidence of a flight)
    recordings_s: tuple[float, ...] = ()
    #: healthy patterns fly in blocks of this many flights, each after the first under the
    #: test station's conditions with probability 1/2 (drawn over ``STATION_ENVELOPE``); 0:
    #: never. Training then learns the conditions as covariates, steps within a unit's life
    #: included, as an operator sets them
    condition_blocks: int = 0


#: the test station's conditions a design's healthy blocks are drawn over (log-uniformly for
#: the scales): inside the ranges the station accepts (server.schemas), and out to the
#: bounds an operator is promised quiet at (ambient -30/+30 K, load x0.5/x2, command x2)
STATION_ENVELOPE: dict[str, tuple[float, float]] = {
    "ambient_offset_k": (-30.0, 30.0), "load_scale": (0.5, 2.0), "command_scale": (0.5, 2.0)}

#: the design campaign's sensor study: per sensor, this many of its healthy patterns flown
#: again with that sensor's noise multiplied by SENSOR_STUDY_NOISE on every actuator (the same
#: flights, seeds and noise draws as their twins): training learns from the pairs what a
#: noisier sensor does to each feature, loops included (server.phm.sensor_health)
SENSOR_STUDY_PATTERNS = 2
SENSOR_STUDY_NOISE = 2.0
#: a study pattern flies the first this many flights of its twin: the pairs measure a noise
#: ratio, which a few thousand paired flights pin down; a long healthy life adds no more
SENSOR_STUDY_FLIGHTS = 50

SCALES: dict[str, dict[str, ScaleConfig]] = {
    # Quick scale: big enough for honest statistics in CI (>= 250 healthy verification
    # flights on 10 aircraft, >= 3 patterns per mode), small enough for ~1 min per campaign.
    "quick": {
        "design": ScaleConfig(duration_s=60.0, healthy_patterns=10, healthy_flights=12,
                              patterns_per_mode=6, render_every=21, apriori_flights=6,
                              apriori_onset=2, span_flights=ENVELOPE_FLIGHTS, span_draw="log"),
        "verification": ScaleConfig(duration_s=60.0, healthy_patterns=10, healthy_flights=25,
                                    patterns_per_mode=3, render_every=21, apriori_flights=6,
                                    apriori_onset=2),
    },
    "paper": {
        "design": ScaleConfig(duration_s=120.0, healthy_patterns=10, healthy_flights=50,
                              patterns_per_mode=10, render_every=11, apriori_flights=8,
                              apriori_onset=2),
        "verification": ScaleConfig(duration_s=120.0, healthy_patterns=25, healthy_flights=4,
                                    patterns_per_mode=25, render_every=21, apriori_flights=8,
                                    apriori_onset=2),
    },
    # The paper's protocol (section 4.3): every flight of every pattern rendered, 25 patterns
    # per mode on 10 unseen aircraft; meant to be streamed (features kept, raw logs sampled).
    # Healthy cycles as long as the fault runs (150-400 flights, section 5.1): two flights a
    # day, so a cycle spans 2.5-7 months of one base's seasons; the design's ten run half a
    # year each (300-400 flights), starting in different months, so training sees every
    # season at every base and both winglet roles over months of service.
    "protocol": {
        "design": ScaleConfig(duration_s=120.0, healthy_patterns=10,
                              healthy_flights=(300, 400),
                              patterns_per_mode=10, render_every=1, apriori_flights=8,
                              apriori_onset=2, span_flights=ENVELOPE_FLIGHTS, span_draw="log"),
        "verification": ScaleConfig(duration_s=120.0, healthy_patterns=25,
                                    healthy_flights=(150, 400),
                                    patterns_per_mode=25, render_every=1, apriori_flights=8,
                                    apriori_onset=2),
    },
    # The shipped model's design (server/data/demo_model.json): the quick design's fault runs,
    # with the protocol design's long healthy cycles (300-400 flights: every season at each
    # base), flown as a fleet in service and on the test station flies them: recordings of
    # 60 s (the demo's), 120 s (the protocol's) and 300 s, the station's conditions in
    # blocks of 40 flights. Its verification: 10 unseen aircraft, 300 healthy flights each.
    "shipped": {
        "design": ScaleConfig(duration_s=60.0, healthy_patterns=10, healthy_flights=(300, 400),
                              patterns_per_mode=6, render_every=21, apriori_flights=6,
                              apriori_onset=2, span_flights=ENVELOPE_FLIGHTS, span_draw="log",
                              recordings_s=(60.0, 60.0, 60.0, 120.0, 300.0),
                              condition_blocks=40),
        "verification": ScaleConfig(duration_s=60.0, healthy_patterns=10, healthy_flights=300,
                                    patterns_per_mode=3, render_every=21, apriori_flights=6,
                                    apriori_onset=2),
    },
    # The same protocol reduced for CI: every flight, a few patterns per mode, short
    # recordings and fast faults (a regression test of the machinery, not a figure).
    "ci": {
        "design": ScaleConfig(duration_s=30.0, healthy_patterns=10, healthy_flights=6,
                              patterns_per_mode=2, render_every=1, apriori_flights=4,
                              apriori_onset=2, span_flights=(15.0, 30.0)),
        "verification": ScaleConfig(duration_s=30.0, healthy_patterns=10, healthy_flights=6,
                                    patterns_per_mode=2, render_every=1, apriori_flights=4,
                                    apriori_onset=2, span_flights=(15.0, 30.0)),
    },
}


#: the noise field of each sensor in :class:`~sim_worker.params.SensorParams`
_NOISE_FIELD = {"current": "current_noise_a", "voltage": "voltage_noise_v",
                "resolver": "resolver_noise_rad", "lvdt": "lvdt_noise_m"}
_FAULT_KINDS = ("noise", "drift")


@dataclass(frozen=True)
class SensorFault:
    """One degraded sensor of one actuator (sensor-health studies), on every aircraft.

    ``noise``: that actuator's noise of that sensor multiplied by ``value`` (> 0, on top of
    ``noise_scale``). ``drift`` (LVDT only): its offset grows by ``value`` metres per flight,
    rigging offset + value x flight index of the pattern. Spec: ``WT.lvdt:noise=2``,
    ``WL1.lvdt:drift=1e-06``.
    """

    position: str
    sensor: str
    kind: str
    value: float

    def __post_init__(self) -> None:
        if self.position not in POSITIONS:
            raise ValueError(f"unknown position {self.position!r}; expected one of "
                             f"{', '.join(POSITIONS)}")
        if self.sensor not in SENSORS:
            raise ValueError(f"unknown sensor {self.sensor!r}; expected one of "
                             f"{', '.join(SENSORS)}")
        if self.kind not in _FAULT_KINDS:
            raise ValueError(f"unknown sensor fault {self.kind!r}; expected noise or drift")
        if self.kind == "drift" and self.sensor != "lvdt":
            raise ValueError(f"drift is an LVDT fault, not a {self.sensor} one")
        value = float(self.value)
        if not math.isfinite(value):
            raise ValueError(f"{self.kind} must be finite, got {value}")
        if self.kind == "noise" and not value > 0:
            raise ValueError(f"noise factor must be positive, got {value:g}")
        object.__setattr__(self, "value", value)  # a plain float: the spec is canonical

    @classmethod
    def parse(cls, spec: str) -> SensorFault:
        """``<POSITION>.<SENSOR>:noise=<factor>`` or ``<POSITION>.lvdt:drift=<m per flight>``."""
        target, sep, setting = spec.strip().partition(":")
        position, dot, sensor = target.partition(".")
        kind, eq, text = setting.partition("=")
        if not (sep and dot and eq):
            raise ValueError(f"sensor fault {spec!r} is not POSITION.SENSOR:noise=FACTOR or "
                             "POSITION.lvdt:drift=METRES")
        try:
            value = float(text)
        except ValueError:
            raise ValueError(f"sensor fault {spec!r}: {text!r} is not a number") from None
        return cls(position.strip(), sensor.strip(), kind.strip(), value)

    @property
    def spec(self) -> str:
        # repr round-trips the float exactly; "2.0" is written "2"
        text = repr(self.value)
        return f"{self.position}.{self.sensor}:{self.kind}=" + text.removesuffix(".0")


def _sensor_faults(faults: Iterable[SensorFault | str] | None) -> tuple[SensorFault, ...]:
    """Faults (specs parsed) in a canonical order, so that the settings of a campaign do not
    depend on the order they were given in; one fault per position, sensor and kind."""
    parsed = [f if isinstance(f, SensorFault) else SensorFault.parse(f) for f in faults or ()]
    seen: set[tuple[str, str, str]] = set()
    for f in parsed:
        key = (f.position, f.sensor, f.kind)
        if key in seen:
            raise ValueError(f"sensor fault {f.position}.{f.sensor}:{f.kind} given twice")
        seen.add(key)
    return tuple(sorted(parsed, key=lambda f: (POSITIONS.index(f.position),
                                               SENSORS.index(f.sensor), f.kind)))


def _seed(*key: int) -> int:
    return int(np.random.SeedSequence(list(key)).generate_state(1, dtype=np.uint64)[0] >> 1)


def fleet_for(kind: str, seed: int, *, bases: tuple[str, ...] | None = None,
              noise_scale: float = 1.0,
              sensor_faults: Iterable[SensorFault | str] = ()) -> list[Aircraft]:
    """The ten aircraft of a campaign; verification tails and seeds never equal design ones.

    ``bases`` (robustness studies) cycles the given bases over the ten aircraft instead of
    4 Turin / 3 Vancouver / 3 Abu Dhabi; ``noise_scale`` multiplies every sensor's noise
    (currents, voltages, resolver, LVDT; offsets and quantisation unchanged). A ``noise``
    sensor fault multiplies one position's noise of one sensor further; a ``drift`` leaves
    the fleet as rigged (it is flown per flight, see :func:`_at_flight`). Tails and aircraft
    seeds depend on none of these.
    """
    code = _KIND_CODE[kind]
    prefix = "I-DSG" if kind == "design" else "I-VER"
    order = FLEET_BASES if not bases else tuple(bases[i % len(bases)]
                                                 for i in range(len(FLEET_BASES)))
    fleet = [build_aircraft(f"{prefix}{i + 1:02d}", base, _seed(seed, code, i))
             for i, base in enumerate(order)]
    if noise_scale != 1.0:
        fleet = [_with_noise(a, noise_scale) for a in fleet]
    noisy = [f for f in _sensor_faults(sensor_faults) if f.kind == "noise"]
    if noisy:
        fleet = [_with_sensor_noise(a, noisy) for a in fleet]
    return fleet


def _with_noise(aircraft: Aircraft, factor: float) -> Aircraft:
    def scaled(p: Any) -> Any:
        sen = p.sensors
        return p.with_(sensors=replace(
            sen, current_noise_a=sen.current_noise_a * factor,
            voltage_noise_v=sen.voltage_noise_v * factor,
            resolver_noise_rad=sen.resolver_noise_rad * factor,
            lvdt_noise_m=sen.lvdt_noise_m * factor))

    return replace(aircraft, ema={pos: scaled(p) for pos, p in aircraft.ema.items()})


def _with_sensor_noise(aircraft: Aircraft, faults: Iterable[SensorFault]) -> Aircraft:
    ema = dict(aircraft.ema)
    for f in faults:
        sen, field = ema[f.position].sensors, _NOISE_FIELD[f.sensor]
        ema[f.position] = ema[f.position].with_(
            sensors=replace(sen, **{field: getattr(sen, field) * f.value}))
    return replace(aircraft, ema=ema)


def _at_flight(aircraft: Aircraft, faults: Iterable[SensorFault], index: int) -> Aircraft:
    """The aircraft as flown at flight ``index`` of a pattern: each drifting LVDT's offset
    grown linearly from its rigging offset (the kernel reads the offset from the parameter
    row, so the drift acts in the loop that closes on the LVDT, as a real one would)."""
    flown = aircraft
    for f in faults:
        if f.kind == "drift":
            rigging = aircraft.offsets[f.position][3]
            flown = flown.with_lvdt_offset(f.position, rigging + f.value * index)
    return flown


@dataclass(frozen=True)
class PatternSpec:
    id: str
    number: int
    aircraft_index: int
    mode: str
    position: str | None
    n_flights: int  # healthy / a priori
    onset: int
    seed: int
    day_offset: float
    sensor_study: str | None = None  # the sensor flown noisier (design sensor study)
    twin: str | None = None  # the healthy pattern it repeats


def _sensor_study(specs: list[PatternSpec], healthy_patterns: int) -> list[PatternSpec]:
    """The sensor-study patterns of a design campaign: twins of its first healthy patterns."""
    out: list[PatternSpec] = []
    for si, sensor in enumerate(SENSORS):
        for j in range(SENSOR_STUDY_PATTERNS):
            twin = specs[(si * SENSOR_STUDY_PATTERNS + j) % healthy_patterns]
            out.append(replace(twin, id=f"D-sensor-{sensor}-{j + 1:02d}",
                               number=len(specs) + len(out), sensor_study=sensor,
                               twin=twin.id,
                               n_flights=min(twin.n_flights, SENSOR_STUDY_FLIGHTS)))
    return out


def _healthy_length(cfg: ScaleConfig, seed: int, code: int, j: int) -> int:
    """Flights of the ``j``-th healthy pattern: the scale's number, or a draw from its range
    that depends on the campaign's seed and kind and the pattern alone."""
    if isinstance(cfg.healthy_flights, int):
        return cfg.healthy_flights
    lo, hi = (int(v) for v in cfg.healthy_flights)
    return int(np.random.default_rng(_seed(seed, code, 3000 + j)).integers(lo, hi + 1))


def plan_campaign(kind: str, seed: int, scale: str, *,
                  per_mode: int | None = None) -> list[PatternSpec]:
    """All patterns of the campaign, in manifest order. ``per_mode``: every healthy pattern
    but only the first ``per_mode`` patterns of each fault mode (0: the healthy ones alone),
    each numbered and seeded as in the whole campaign, so they fly the same flights."""
    if kind not in _KIND_CODE:
        raise ValueError(f"kind must be one of {sorted(_KIND_CODE)}")
    cfg = SCALES[scale][kind]
    code = _KIND_CODE[kind]
    specs: list[PatternSpec] = []
    n_air = len(FLEET_BASES)

    def add(mode: str, position: str | None, ai: int, n_flights: int, onset: int, j: int) -> None:
        number = len(specs)
        pid = f"{kind[0].upper()}-{mode}-{j + 1:02d}"
        specs.append(PatternSpec(pid, number, ai, mode, position, n_flights, onset,
                                 _seed(seed, code, 1000 + number), day_offset=37.0 * number % 365))

    for j in range(cfg.healthy_patterns):
        add("healthy", None, j % n_air, _healthy_length(cfg, seed, code, j), 0, j)
    for m_i, mode in enumerate(MODES):
        for j in range(cfg.patterns_per_mode):
            ai = (j * 3 + m_i) % n_air
            # a rod end's play is read against the partner drive's LVDT: a winglet drive
            pos = (WINGLET_PAIR[j % 2] if mode == "REWEAR"
                   else POSITIONS[(j + m_i) % len(POSITIONS)])
            if mode in A_PRIORI:
                add(mode, pos, ai, cfg.apriori_flights, cfg.apriori_onset, j)
            else:
                add(mode, pos, ai, 0, cfg.lead_flights, j)
    if kind == "design" and cfg.healthy_patterns:
        specs += _sensor_study(specs, cfg.healthy_patterns)
    if per_mode is not None:
        # the sensor study belongs to the fault-pattern part of a design campaign
        specs = [s for s in specs if (s.mode == "healthy" and not (s.sensor_study and
                                                                  per_mode == 0))
                 or (s.mode != "healthy" and int(s.id.rsplit("-", 1)[1]) <= per_mode)]
    return specs


def execution_order(specs: list[PatternSpec]) -> list[PatternSpec]:
    """The order patterns are simulated in (results are re-ordered by pattern number and do
    not depend on it): the modes' k-th patterns together, round by round, so that a run
    stopped part way (:func:`snapshot_campaign`) holds about the same share of every mode;
    within a round the long fault-to-failure runs first, for load balance."""
    seen: Counter[tuple[str, bool]] = Counter()
    round_of: dict[int, int] = {}
    for s in sorted(specs, key=lambda s: s.number):
        group = (s.mode, s.sensor_study is not None)
        round_of[s.number] = seen[group]
        seen[group] += 1
    return sorted(specs, key=lambda s: (s.sensor_study is not None, round_of[s.number],
                                        s.mode not in PROGRESSIVE, s.number))


def _flight_rng(spec: PatternSpec, index: int, stream: int) -> np.random.Generator:
    return np.random.default_rng([spec.seed, index, stream])


class FlightSink(Protocol):
    """What becomes of a rendered flight: called in the worker that simulated it.

    Returns the flight's file (relative to the campaign's store ``out``, or None if no file
    was kept) and the data stored for it in place of the file (None: nothing). ``describe`` is
    part of the campaign's settings (a resumed campaign must use the same sink); ``finish``
    writes what the sink keeps beside the manifest, once every pattern is done.
    """

    def __call__(self, out: CampaignStore, rel: str, index: int, log: FlightLog,
                 ground_temp_c: float) -> tuple[str | None, dict[str, Any] | None]: ...

    def describe(self) -> dict[str, Any]: ...

    def finish(self, out: CampaignStore, stored: dict[str, dict[str, Any]]) -> None: ...


@dataclass(frozen=True)
class ParquetSink:
    """Every rendered flight written as a flight-log file (``ema-flightlog/1`` Parquet)."""

    def __call__(self, out: CampaignStore | Path, rel: str, index: int, log: FlightLog,
                 ground_temp_c: float) -> tuple[str | None, dict[str, Any] | None]:
        CampaignStore.at(out).write(rel, write_parquet(log))
        return rel, None

    def describe(self) -> dict[str, Any]:
        return {"sink": "parquet"}

    def finish(self, out: CampaignStore | Path, stored: dict[str, dict[str, Any]]) -> None:
        return None


def recording_s(cfg: ScaleConfig, spec: PatternSpec, index: int) -> float:
    """The recording length of a rendered flight [s]: drawn from ``cfg.recordings_s`` with
    the flight's own seed (a sensor-study twin draws its twin's), else ``cfg.duration_s``."""
    if not cfg.recordings_s:
        return cfg.duration_s
    pick = _flight_rng(spec, index, 5).integers(len(cfg.recordings_s))
    return float(cfg.recordings_s[int(pick)])


def block_conditions(cfg: ScaleConfig, spec: PatternSpec, index: int) -> Conditions:
    """The test-station conditions of a healthy pattern's flight: its block's draw (the first
    block nominal: the unit learns its reference as installed; later blocks under conditions
    with probability 1/2, each drawn log-uniformly over ``STATION_ENVELOPE``, the offset
    uniformly)."""
    if not cfg.condition_blocks or spec.mode != "healthy":
        return NO_CONDITIONS
    block = index // cfg.condition_blocks
    rng = np.random.default_rng([spec.seed, block, 6])
    if block == 0 or rng.random() < 0.5:
        return NO_CONDITIONS
    lo, hi = STATION_ENVELOPE["ambient_offset_k"]
    ambient = round(float(rng.uniform(lo, hi)), 1)

    def scale(name: str) -> float:
        low, high = STATION_ENVELOPE[name]
        return round(float(np.exp(rng.uniform(math.log(low), math.log(high)))), 3)

    load = scale("load_scale")
    return Conditions(ambient_offset_k=ambient, load_scale=load,
                      command_scale=scale("command_scale"))


def _render(out: CampaignStore, aircraft: Aircraft, spec: PatternSpec, fault: FaultState,
            index: int, cfg: ScaleConfig, sink: FlightSink,
            sensor_faults: tuple[SensorFault, ...] = ()
            ) -> tuple[str, str | None, Any, dict[str, Any] | None]:
    flight_id = f"{spec.id}-{index:04d}"
    start = flight_start(index, day_offset=spec.day_offset)
    log, summary = simulate_flight(_at_flight(aircraft, sensor_faults, index), fault, index,
                                   _flight_rng(spec, index, 0), flight_id=flight_id,
                                   started_at=start, duration_s=recording_s(cfg, spec, index),
                                   conditions=block_conditions(cfg, spec, index))
    rel, stored = sink(out, f"flights/{aircraft.tail}/{flight_id}.parquet", index, log,
                       _ground_temp(summary))
    return flight_id, rel, summary, stored


def _ground_temp(summary: Any) -> float:
    return round(float(summary.ground_temp_c), 3)


def _flight_entry(flight_id: str, rel: str | None, index: int, fault: FaultState, summary: Any,
                  failure: int | None, started_at: str) -> dict[str, Any]:
    return {
        "flight": flight_id,
        "index": index,
        "file": rel,
        "started_at": started_at,
        "severity": float(fault.severity) if fault.mode != "healthy" else 0.0,
        "severity_norm": float(fault.severity_norm),
        "true_rul_flights": None if failure is None else int(failure - index),
        "block_hours": float(summary.block_hours),
        "ground_temp_c": _ground_temp(summary),
        "measured_summary": {p: {k: round(v, 6) for k, v in asdict(s).items()}
                             for p, s in summary.actuators.items()},
    }


@dataclass(frozen=True)
class PatternTask:
    """Everything a worker needs to run one pattern (it rebuilds the aircraft itself)."""

    out: CampaignStore | str  # a store, or a directory / s3:// URL (AWS S3)
    kind: str
    seed: int
    cfg: ScaleConfig
    spec: PatternSpec
    options: dict[str, Any]
    sink: FlightSink


def run_pattern(task: PatternTask) -> dict[str, Any]:
    """Run one pattern (a task of the pool): its manifest entry, and under ``"stored"`` what
    the sink kept for each rendered flight, by flight id."""
    cfg, spec, sink = task.cfg, task.spec, task.sink
    out = CampaignStore.at(task.out)
    aircraft = fleet_for(task.kind, task.seed, **task.options)[spec.aircraft_index]
    if spec.sensor_study is not None:
        aircraft = _with_sensor_noise(aircraft, [
            SensorFault(p, spec.sensor_study, "noise", SENSOR_STUDY_NOISE) for p in POSITIONS])
    rendered: list[tuple[int, str, str | None, FaultState, Any]] = []
    stored: dict[str, dict[str, Any]] = {}
    failure: int | None = None

    faults = tuple(task.options.get("sensor_faults", ()))

    def render(fault: FaultState, index: int) -> Any:
        fid, rel, summ, data = _render(out, aircraft, spec, fault, index, cfg, sink, faults)
        rendered.append((index, fid, rel, fault, summ))
        if data is not None:
            stored[fid] = data
        return summ

    if spec.mode == "healthy" or spec.mode in A_PRIORI:
        threshold = _constant_run(spec, render)
    else:
        threshold, failure = _fault_to_failure(aircraft, spec, cfg, render)
    flights = [_flight_entry(fid, rel, index, f, summ, failure,
                             flight_start(index, day_offset=spec.day_offset).isoformat())
               | _envelope_entry(cfg, spec, index)
               for index, fid, rel, f, summ in rendered]
    return {
        "entry": {
            "id": spec.id,
            "aircraft": aircraft.tail,
            "mode": spec.mode,
            "position": spec.position,
            "threshold": threshold,
            "onset_flight": spec.onset,
            "failure_flight": failure,
            **_study_entry(spec),
            "flights": flights,
        },
        "stored": stored,
    }


def _envelope_entry(cfg: ScaleConfig, spec: PatternSpec, index: int) -> dict[str, Any]:
    """A flight's recording length and test-station conditions, for a scale that varies them
    (ground truth; a scale that does not keeps its manifest as it was)."""
    out: dict[str, Any] = {}
    if cfg.recordings_s:
        out["recording_s"] = recording_s(cfg, spec, index)
    cond = block_conditions(cfg, spec, index)
    if cond != NO_CONDITIONS:
        out["conditions"] = {k: v for k, v in asdict(cond).items() if v is not None}
    return out


def _study_entry(spec: PatternSpec) -> dict[str, Any]:
    if spec.sensor_study is None:
        return {}
    return {"sensor_study": {"sensor": spec.sensor_study, "noise": SENSOR_STUDY_NOISE,
                             "twin": spec.twin}}


def _position(spec: PatternSpec) -> str:
    """The faulty actuator of a fault pattern; a fault pattern without one is an error."""
    if spec.position is None:
        raise ValueError(f"pattern {spec.id}: a {spec.mode} pattern needs a position")
    return spec.position


def _constant_run(spec: PatternSpec, render: Callable[[FaultState, int], Any]) -> float | None:
    """A healthy cycle, or an a priori fault imposed from ``onset`` on; its threshold."""
    fault_on = healthy()
    if spec.mode in A_PRIORI:
        fault_on = new_fault(spec.mode, _position(spec), np.random.default_rng([spec.seed, 7]))
    for index in range(spec.n_flights):
        render(fault_on if index >= spec.onset else healthy(), index)
    return fault_on.threshold


def _fault_to_failure(aircraft: Aircraft, spec: PatternSpec, cfg: ScaleConfig,
                      render: Callable[[FaultState, int], Any]
                      ) -> tuple[float | None, int | None]:
    """The healthy lead, then the fault advanced flight by flight to failure (every
    ``render_every``-th flight and the failure flight rendered); threshold and failure flight."""
    position = _position(spec)
    ref = reference_summary(aircraft, position, duration_s=cfg.duration_s, seed=spec.seed)
    fault = new_fault(spec.mode, position, np.random.default_rng([spec.seed, 7]),
                      reference=ref, span_range=cfg.span_flights, span_draw=cfg.span_draw)
    for index in range(spec.onset):
        render(healthy(), index)
    for index in range(spec.onset, spec.onset + _MAX_FLIGHTS):
        if fault.failed:
            render(fault, index)
            return fault.threshold, index
        if (index - spec.onset) % cfg.render_every == 0:
            summ = render(fault, index)
        else:
            summ = estimate_summary(aircraft, index, _flight_rng(spec, index, 0),
                                    started_at=flight_start(index, day_offset=spec.day_offset),
                                    duration_s=cfg.duration_s)
        fault = advance_fault(fault, summ, _flight_rng(spec, index, 1))
    return fault.threshold, None


def _completed(tasks: dict[int, PatternTask], workers: int, executor: Executor | None
               ) -> Iterator[tuple[int, dict[str, Any]]]:
    """(task number, result) as each pattern finishes, on ``executor`` if given, else on a
    local process pool of ``workers`` (1: in this process)."""
    if executor is None and workers <= 1:
        for i, task in tasks.items():
            yield i, run_pattern(task)
        return
    pool = executor if executor is not None else ProcessPoolExecutor(max_workers=workers)
    try:
        futures = {pool.submit(run_pattern, task): i for i, task in tasks.items()}
        for fut in as_completed(futures):
            yield futures[fut], fut.result()
    finally:
        if executor is None:
            pool.shutdown(wait=True, cancel_futures=True)


def _settings(kind: str, seed: int, scale: str, cfg: ScaleConfig, options: dict[str, Any],
              sink: FlightSink) -> dict[str, Any]:
    """What determines the campaign's content: a resumed campaign must match it exactly."""
    settings = {"format": FORMAT, "kind": kind, "seed": int(seed), "scale": scale,
                "config": _config_settings(cfg),
                "bases": list(options["bases"]) if options["bases"] else None,
                "noise_scale": options["noise_scale"], "sink": sink.describe(),
                "winglet_mode": DEFAULT_WINGLET_MODE.value}
    if kind == "design":
        settings["sensor_study"] = {"patterns": SENSOR_STUDY_PATTERNS,
                                    "noise": SENSOR_STUDY_NOISE}
    if options["sensor_faults"]:
        # only when given: campaigns without sensor faults keep the settings they had
        # before the option existed, so finished ones are still recognised
        settings["sensor_faults"] = [f.spec for f in options["sensor_faults"]]
    return settings


def _config_settings(cfg: ScaleConfig) -> dict[str, Any]:
    """The scale config as settings; a uniform span draw is left out, so campaigns finished
    before the draw could be chosen are still recognised."""
    out = asdict(cfg)
    if out["span_draw"] == "uniform":
        del out["span_draw"]
    # likewise the envelope, when the scale does not vary it
    for key in ("recordings_s", "condition_blocks"):
        if not out[key]:
            del out[key]
    return out


_PROGRESS = "progress"


class _Progress:
    """Finished patterns of an interrupted run, one file each in ``DIR/progress/``; a finished
    pattern is never simulated again. Removed once the manifest is written."""

    def __init__(self, out: CampaignStore | Path, settings: dict[str, Any]) -> None:
        self.out = CampaignStore.at(out)
        rel = f"{_PROGRESS}/settings.json"
        text = json.dumps(settings, sort_keys=True)
        held = self.out.read_text(rel)
        if held is not None and held != text:
            raise ValueError(f"{self.out} holds an unfinished campaign with other settings "
                             f"(see {self.out}/{rel}); resume it with the same options or use "
                             "another directory")
        if held is None:
            self.out.write(rel, text.encode())

    def done(self, spec: PatternSpec) -> dict[str, Any] | None:
        text = self.out.read_text(_progress_file(spec))
        return None if text is None else json.loads(text)

    def save(self, spec: PatternSpec, result: dict[str, Any]) -> None:
        self.out.write(_progress_file(spec), json.dumps(result).encode())

    def remove(self) -> None:
        self.out.remove_dir(_PROGRESS)


def _progress_file(spec: PatternSpec) -> str:
    return f"{_PROGRESS}/{spec.number:04d}.json"


def run_campaign(kind: str, out_dir: str | Path | CampaignStore, *, seed: int,
                 scale: str = "quick",
                 workers: int | None = None, progress: bool = True,
                 bases: tuple[str, ...] | None = None, noise_scale: float = 1.0,
                 sensor_faults: Iterable[SensorFault | str] = (),
                 render_every: int | None = None,
                 span_flights: tuple[float, float] | None = None,
                 span_draw: str | None = None,
                 sink: FlightSink | None = None,
                 executor: Executor | None = None,
                 per_mode: int | None = None,
                 recordings_s: Iterable[float] | None = None) -> dict[str, Any]:
    """Write a campaign and its manifest; returns the manifest.

    Manifest (``DIR/manifest.json``)::

        {"format": "ema-campaign/1", "kind", "seed", "scale", "duration_s", "render_every",
         "lead_flights", "span_flights", "noise_scale", "bases", "sensor_faults", "sink",
         "aircraft": [{"tail", "base", "climate", "serials": {pos: serial}, "params": {...}}],
         "patterns": [{"id", "aircraft", "mode", "position", "threshold", "onset_flight",
                       "failure_flight", "flights": [{"flight", "index", "file", "started_at",
                       "severity", "severity_norm", "true_rul_flights", "block_hours",
                       "ground_temp_c", "measured_summary"}]}]}

    A design campaign ends with its sensor study: patterns with ``"sensor_study": {"sensor",
    "noise", "twin"}``, healthy, each the twin pattern again with one sensor noisier.

    A flight's ``file`` is None when the sink kept no log of it (a streamed campaign keeps
    its features instead). ``sensor_faults`` (:class:`SensorFault` or their specs) degrade
    one sensor of one actuator on every aircraft, written as their specs
    (``["WT.lvdt:noise=2"]``, empty when none). ``render_every`` overrides the scale's
    rendering step of fault-to-failure runs (1 renders every flight, as a fleet in service
    downloads every one); ``span_flights`` the range of expected fault-to-failure spans,
    ``span_draw`` how a pattern draws from it ("uniform" or "log", log-uniform; default the
    scale's: the quick and protocol designs span the envelope log-uniformly). The
    winglet tab flies active-standby (``fleet.DEFAULT_WINGLET_MODE``, recorded in the manifest
    as ``"winglet_mode"``).
    ``per_mode`` flies every healthy pattern and only the first ``per_mode`` patterns of each
    fault mode (0: the healthy ones alone, for false alarms over long healthy lives), the
    same flights as in the whole campaign.
    ``recordings_s`` overrides the scale's recording lengths: every rendered flight draws its
    own from them (one value: every flight that long); a scale that varies them, and its
    test-station condition blocks, records each flight's under ``"recording_s"`` and
    ``"conditions"``.
    ``out_dir`` is a directory, ``s3://bucket/prefix`` (AWS S3) or a
    :class:`~server.campaign_store.CampaignStore` (another S3 server's); every file of the
    campaign goes there, the kept logs straight from the workers.
    ``sink`` decides what is kept of a rendered flight (default: its Parquet file). Patterns
    run on ``executor`` (any ``concurrent.futures.Executor``, e.g. a Dask client's) if given,
    else on a local pool of ``workers`` processes; the output does not depend on either. An
    interrupted run resumes where it stopped when called again with the same arguments.
    """
    if scale not in SCALES:
        raise ValueError(f"scale must be one of {sorted(SCALES)}")
    if bases and not set(bases) <= set(BASES):
        raise ValueError(f"bases must be among {sorted(BASES)}")
    if not noise_scale > 0:
        raise ValueError("noise_scale must be positive")
    if per_mode is not None and (isinstance(per_mode, bool) or int(per_mode) != per_mode
                                 or per_mode < 0):
        raise ValueError(f"per_mode must be a count of patterns (>= 0), got {per_mode!r}")
    faults = _sensor_faults(sensor_faults)
    cfg = _scale_config(scale, kind, render_every, span_flights, span_draw, recordings_s)
    sink = sink if sink is not None else ParquetSink()
    from tqdm import tqdm

    from .kernel import warm_up

    out = CampaignStore.at(out_dir)
    # a plain tuple of frozen dataclasses: pickled as is to pool and Dask workers
    options: dict[str, Any] = {"bases": tuple(bases) if bases else None,
                               "noise_scale": float(noise_scale),
                               "sensor_faults": faults}
    settings = _settings(kind, seed, scale, cfg, options, sink)
    if per_mode is not None:
        settings["per_mode"] = int(per_mode)  # only when given, as sensor_faults
    finished = _finished_manifest(out, settings)
    if finished is not None:
        return finished
    warm_up()  # compile (or load the cache) once before forking workers
    specs = plan_campaign(kind, seed, scale, per_mode=per_mode)
    fleet = fleet_for(kind, seed, **options)
    store = _Progress(out, settings)
    results = {s.number: r for s in specs if (r := store.done(s)) is not None}
    todo = {s.number: PatternTask(out, kind, seed, cfg, s, options, sink)
            for s in execution_order(specs) if s.number not in results}
    bar = tqdm(total=len(specs), initial=len(results), desc=f"{kind} campaign",
               unit="pattern", disable=not progress)
    by_number = {s.number: s for s in specs}  # a part's numbers are the whole campaign's
    for number, res in _completed(todo, workers or os.cpu_count() or 1, executor):
        store.save(by_number[number], res)
        results[number] = res
        bar.update(1)
    bar.close()
    ordered = [results[s.number] for s in specs]
    sink.finish(out, {fid: data for r in ordered for fid, data in r["stored"].items()})
    manifest = _manifest(settings, cfg, fleet, [r["entry"] for r in ordered])
    out.write("manifest.json", json.dumps(manifest, indent=1).encode())
    out.write(SETTINGS_FILE, json.dumps(settings, sort_keys=True).encode())
    store.remove()
    return manifest


def snapshot_campaign(out_dir: str | Path | CampaignStore, snap_dir: str | Path | CampaignStore,
                      *, sink: FlightSink | None = None) -> dict[str, Any]:
    """The patterns an unfinished campaign in ``out_dir`` has finished so far, written to
    ``snap_dir`` as a campaign of their own, so that a run of hours can be scored before it
    ends; returns its manifest. The run itself is not touched and resumes as before.

    The manifest is the full campaign's for the finished patterns, in pattern order, plus
    ``"partial": {"patterns": finished, "of": planned}``; ``sink`` (the run's, default
    :class:`ParquetSink`) writes what it keeps of them, and ``snap_dir/flights`` links to the
    run's kept logs (between two local directories; else the finished patterns' kept logs are
    copied). A finished campaign, or a sink other than the run's, is refused.
    """
    out, snap = CampaignStore.at(out_dir), CampaignStore.at(snap_dir)
    sink = sink if sink is not None else ParquetSink()
    if out.exists(SETTINGS_FILE):
        raise ValueError(f"{out} is a finished campaign: score it directly")
    text = out.read_text(f"{_PROGRESS}/settings.json")
    if text is None:
        raise ValueError(f"{out}: no campaign in progress (no {_PROGRESS}/settings.json)")
    settings = json.loads(text)
    if settings["sink"] != sink.describe():
        raise ValueError(f"{out} was run with the sink {settings['sink']}, not "
                         f"{sink.describe()}")
    fields: dict[str, Any] = {k: tuple(v) if isinstance(v, list) else v
                              for k, v in settings["config"].items()}
    cfg = ScaleConfig(**fields)
    specs = plan_campaign(settings["kind"], settings["seed"], settings["scale"],
                          per_mode=settings.get("per_mode"))
    store = _Progress(out, settings)
    done = [r for s in specs if (r := store.done(s)) is not None]
    fleet = fleet_for(settings["kind"], settings["seed"],
                      bases=tuple(settings["bases"]) if settings["bases"] else None,
                      noise_scale=settings["noise_scale"],
                      sensor_faults=_sensor_faults(settings.get("sensor_faults")))
    entries = [r["entry"] for r in done]
    _share_logs(out, snap, [fl["file"] for e in entries for fl in e["flights"] if fl["file"]])
    sink.finish(snap, {fid: data for r in done for fid, data in r["stored"].items()})
    manifest = _manifest(settings, cfg, fleet, entries)
    manifest["partial"] = {"patterns": len(done), "of": len(specs)}
    snap.write("manifest.json", json.dumps(manifest, indent=1).encode())
    return manifest


def _share_logs(out: CampaignStore, snap: CampaignStore, files: list[str]) -> None:
    """The run's kept logs seen from the snapshot: ``flights`` a link to the run's between
    local directories (the run goes on writing there), else the given files copied."""
    here, there = out.local_dir(), snap.local_dir()
    if here is None or there is None:
        for rel in files:
            if not snap.exists(rel):
                snap.write(rel, out.read(rel))
        return
    there.mkdir(parents=True, exist_ok=True)
    if not (there / "flights").exists():
        (there / "flights").symlink_to((here / "flights").resolve(), target_is_directory=True)


def _manifest(settings: dict[str, Any], cfg: ScaleConfig, fleet: list[Aircraft],
              patterns: list[dict[str, Any]]) -> dict[str, Any]:
    return {
        "format": FORMAT,
        "kind": settings["kind"],
        "seed": settings["seed"],
        "scale": settings["scale"],
        "duration_s": cfg.duration_s,
        "render_every": cfg.render_every,
        "lead_flights": cfg.lead_flights,
        "span_flights": list(cfg.span_flights),
        "noise_scale": settings["noise_scale"],
        "bases": settings["bases"],
        "sensor_faults": settings.get("sensor_faults", []),
        "winglet_mode": settings.get("winglet_mode", WingletMode.ACTIVE_ACTIVE.value),
        "sink": settings["sink"],
        "aircraft": [{"tail": a.tail, "base": a.base, "climate": BASES[a.base],
                      "serials": dict(a.serials), "params": a.params_summary()} for a in fleet],
        "patterns": patterns,
    }


def _scale_config(scale: str, kind: str, render_every: int | None,
                  span_flights: tuple[float, float] | None,
                  span_draw: str | None = None,
                  recordings_s: Iterable[float] | None = None) -> ScaleConfig:
    cfg = SCALES[scale][kind]
    if recordings_s is not None:
        lengths = tuple(float(v) for v in recordings_s)
        if not lengths or not all(math.isfinite(v) and 10.0 <= v <= 600.0 for v in lengths):
            raise ValueError(f"recording lengths must lie in 10..600 s, got {lengths}")
        cfg = replace(cfg, recordings_s=lengths)
    if span_draw is not None:
        if span_draw not in SPAN_DRAWS:
            raise ValueError(f"span_draw must be one of {SPAN_DRAWS}, got {span_draw!r}")
        cfg = replace(cfg, span_draw=span_draw)
    if render_every is not None:
        if isinstance(render_every, bool) or not isinstance(render_every, int) \
                or render_every < 1 or render_every % 2 == 0:
            raise ValueError("render_every must be a positive odd int: the winglet's active "
                             "drive alternates by flight, so an even step would render a "
                             "faulty winglet drive in one role only")
        cfg = replace(cfg, render_every=render_every)
    if span_flights is not None:
        lo, hi = (float(v) for v in span_flights)
        if not (math.isfinite(lo) and math.isfinite(hi) and 1.0 <= lo <= hi <= _MAX_SPAN):
            raise ValueError(f"span range must satisfy 1 <= low <= high <= {_MAX_SPAN:g} "
                             f"flights, got {lo:g}..{hi:g}")
        cfg = replace(cfg, span_flights=(lo, hi))
    return cfg


def _finished_manifest(out: CampaignStore, settings: dict[str, Any]) -> dict[str, Any] | None:
    """The manifest of a campaign already finished in ``out`` with these settings; a finished
    campaign with other settings is refused (it is never overwritten)."""
    held = out.read_text(SETTINGS_FILE)
    if held is None:
        return None  # nothing finished here, or a campaign of an older simulator: regenerate
    if held != json.dumps(settings, sort_keys=True):
        raise ValueError(f"{out} already holds a campaign with other settings (see "
                         f"{out}/{SETTINGS_FILE}); use another directory")
    return json.loads(out.read("manifest.json"))
