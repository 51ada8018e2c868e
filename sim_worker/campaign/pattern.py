"""Running patterns (the pool's tasks, :func:`run_patterns`): their flights simulated, each
rendered one given to the campaign's :class:`FlightSink`, and each pattern's manifest entry.

A pattern is a generator (:func:`pattern_flights`) that yields each flight it renders and is
sent that flight's download and summary back, since a fault advances on the summary of the
flight before. Several patterns run in lockstep, their next flights simulated together in the
kernel's SIMD lanes (:func:`~sim_worker.flight.simulate_flights`); each flight equals its lone
simulation bit for bit, so a pattern's output does not depend on what flies beside it.

Fault-to-failure runs start with ``lead_flights`` healthy flights (the actuator's service
before the fault, every one rendered), then advance the progression law every flight from the
onset; only every ``render_every``-th flight after the onset (and the failure flight) is
simulated at 12 kHz and given to the sink; the others use the quasi-static
:func:`~sim_worker.flight.estimate_summary` of the same flight conditions (which agrees with
the rendered flights on the wear drivers of either role), so a run's expected life does not
depend on ``render_every``. A concurrent pattern (two faults at once) runs as
:mod:`.concurrent` says, its manifest entry holding each fault's truth.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Generator, Iterator
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from server.campaign_store import CampaignStore
from server.flightlog import FlightLog, write_parquet
from server.vocabulary import POSITIONS

from ..conditions import NO_CONDITIONS
from ..faults import (
    A_PRIORI,
    Faults,
    FaultState,
    FlightSummary,
    advance_fault,
    healthy,
    new_fault,
)
from ..fleet import Aircraft
from ..flight import (
    LANES,
    FlightSpec,
    estimate_summary,
    flight_start,
    reference_summary,
    simulate_flights,
)
from .concurrent import ConcurrentRun, concurrent_run, fault_truths, pattern_faults
from .planning import PatternSpec, block_conditions, fleet_for, flight_rng, recording_s
from .scales import MAX_FLIGHTS, SENSOR_STUDY_NOISE, ScaleConfig
from .sensor_faults import SensorFault, at_flight, with_sensor_noise

__all__ = ["FlightSink", "ParquetSink", "PatternTask", "iter_patterns", "pattern_flights",
           "run_pattern", "run_patterns"]

#: a pattern's run: yields the flights it renders, is sent each one's (log, summary), returns
#: its result (manifest entry and what the sink stored)
PatternRun = Generator[FlightSpec, tuple[FlightLog, FlightSummary], dict[str, Any]]
#: a rendered flight of a pattern: yields its spec, returns its summary
_Rendered = Generator[FlightSpec, tuple[FlightLog, FlightSummary], Any]


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


def _flight_spec(aircraft: Aircraft, spec: PatternSpec, fault: Faults, index: int,
                 cfg: ScaleConfig, sensor_faults: tuple[SensorFault, ...]) -> FlightSpec:
    return FlightSpec(at_flight(aircraft, sensor_faults, index), fault, index,
                      flight_rng(spec, index, 0), flight_id=f"{spec.id}-{index:04d}",
                      started_at=flight_start(index, day_offset=spec.day_offset),
                      duration_s=recording_s(cfg, spec, index),
                      conditions=block_conditions(cfg, spec, index))


def _render(out: CampaignStore, aircraft: Aircraft, spec: PatternSpec, fault: Faults,
            index: int, cfg: ScaleConfig, sink: FlightSink,
            sensor_faults: tuple[SensorFault, ...] = ()
            ) -> Generator[FlightSpec, tuple[FlightLog, FlightSummary],
                           tuple[str, str | None, Any, dict[str, Any] | None]]:
    flight = _flight_spec(aircraft, spec, fault, index, cfg, sensor_faults)
    flight_id = str(flight.flight_id)
    log, summary = yield flight
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
        **_flown(summary),
    }


def _flown(summary: Any) -> dict[str, Any]:
    """What a rendered flight did: its block hours, ground temperature, actuator summaries."""
    return {
        "block_hours": float(summary.block_hours),
        "ground_temp_c": _ground_temp(summary),
        "measured_summary": {p: {k: round(v, 6) for k, v in asdict(s).items()}
                             for p, s in summary.actuators.items()},
    }


def _concurrent_flight_entry(flight_id: str, rel: str | None, index: int, summary: Any,
                             run: ConcurrentRun, started_at: str) -> dict[str, Any]:
    """A concurrent pattern's rendered flight: each fault's truth under ``faults`` (none on
    a lead flight), no single-fault keys."""
    return {"flight": flight_id, "index": index, "file": rel, "started_at": started_at,
            **_flown(summary), "faults": fault_truths(run, index)}


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
    """Run one pattern alone: its manifest entry, and under ``"stored"`` what the sink kept
    for each rendered flight, by flight id."""
    return run_patterns([task], lanes=1)[0]


def run_patterns(tasks: list[PatternTask], *, lanes: int = LANES) -> list[dict[str, Any]]:
    """Run patterns in lockstep (:func:`iter_patterns`; a task of the pool): each result as
    :func:`run_pattern` gives it, in the tasks' order."""
    results = dict(iter_patterns(tasks, lanes=lanes))
    return [results[i] for i in range(len(tasks))]


def iter_patterns(tasks: list[PatternTask], *, lanes: int = LANES
                  ) -> Iterator[tuple[int, dict[str, Any]]]:
    """Run patterns in lockstep, up to ``lanes`` at once: each next flight of the running
    patterns simulated in one kernel call, a finished pattern's place taken by the next task.
    Yields (task index, result) as each pattern finishes."""
    results: dict[int, dict[str, Any]] = {}
    waiting = deque(enumerate(tasks))
    running: list[tuple[int, PatternRun, FlightSpec]] = []
    while waiting or running:
        while waiting and len(running) < lanes:
            i, task = waiting.popleft()
            _advance(i, pattern_flights(task), None, running, results)
        if running:
            flown = simulate_flights([flight for _, _, flight in running], lanes=lanes)
            batch, running[:] = list(running), []
            try:
                for (i, run, _), outputs in zip(batch, flown, strict=True):
                    _advance(i, run, outputs, running, results)
            except Exception:
                yield from results.items()  # what finished in this round is kept, then the error
                raise
        yield from results.items()
        results.clear()


def _advance(i: int, run: PatternRun, outputs: tuple[FlightLog, FlightSummary] | None,
             running: list[tuple[int, PatternRun, FlightSpec]],
             results: dict[int, dict[str, Any]]) -> None:
    """Send a pattern its last flight's outputs (None: start it); keep it running with its
    next flight, or store its result when it is done."""
    try:
        flight = next(run) if outputs is None else run.send(outputs)
    except StopIteration as done:
        results[i] = done.value
        return
    running.append((i, run, flight))


def pattern_flights(task: PatternTask) -> PatternRun:
    """One pattern's run (:data:`PatternRun`): its result is what :func:`run_pattern` gives."""
    cfg, spec, sink = task.cfg, task.spec, task.sink
    out = CampaignStore.at(task.out)
    aircraft = fleet_for(task.kind, task.seed, **task.options)[spec.aircraft_index]
    if spec.sensor_study is not None:
        aircraft = with_sensor_noise(aircraft, [
            SensorFault(p, spec.sensor_study, "noise", SENSOR_STUDY_NOISE) for p in POSITIONS])
    rendered: list[tuple[int, str, str | None, Faults, Any]] = []
    stored: dict[str, dict[str, Any]] = {}
    failure: int | None = None

    faults = tuple(task.options.get("sensor_faults", ()))

    def render(fault: Faults, index: int, units: Aircraft = aircraft) -> _Rendered:
        fid, rel, summ, data = yield from _render(out, units, spec, fault, index, cfg, sink,
                                                  faults)
        rendered.append((index, fid, rel, fault, summ))
        if data is not None:
            stored[fid] = data
        return summ

    if spec.faults:
        run = yield from concurrent_run(aircraft, spec, cfg, render)
        return {"entry": {
            "id": spec.id, "aircraft": aircraft.tail, "mode": spec.mode,
            "faults": pattern_faults(run),
            "flights": [_concurrent_flight_entry(
                fid, rel, index, summ, run,
                flight_start(index, day_offset=spec.day_offset).isoformat())
                | _envelope_entry(cfg, spec, index) for index, fid, rel, _, summ in rendered]},
            "stored": stored}
    if spec.mode == "healthy" or spec.mode in A_PRIORI:
        threshold = yield from _constant_run(spec, render)
    else:
        threshold, failure = yield from _fault_to_failure(aircraft, spec, cfg, render)
    flights = [_flight_entry(fid, rel, index, _single(f), summ, failure,
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


def _single(fault: Faults) -> FaultState:
    """The fault a single-fault pattern flew on a flight (it flies one at a time)."""
    if not isinstance(fault, FaultState):
        raise TypeError("a single-fault pattern flies one fault a flight")
    return fault


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


def _constant_run(spec: PatternSpec, render: Callable[[FaultState, int], _Rendered]
                  ) -> Generator[FlightSpec, tuple[FlightLog, FlightSummary], float | None]:
    """A healthy cycle, or an a priori fault imposed from ``onset`` on; its threshold."""
    fault_on = healthy()
    if spec.mode in A_PRIORI:
        fault_on = new_fault(spec.mode, _position(spec), np.random.default_rng([spec.seed, 7]))
    for index in range(spec.n_flights):
        yield from render(fault_on if index >= spec.onset else healthy(), index)
    return fault_on.threshold


def _fault_to_failure(aircraft: Aircraft, spec: PatternSpec, cfg: ScaleConfig,
                      render: Callable[[FaultState, int], _Rendered]
                      ) -> Generator[FlightSpec, tuple[FlightLog, FlightSummary],
                                     tuple[float | None, int | None]]:
    """The healthy lead, then the fault advanced flight by flight to failure (every
    ``render_every``-th flight and the failure flight rendered); threshold and failure flight."""
    position = _position(spec)
    ref = reference_summary(aircraft, position, duration_s=cfg.duration_s, seed=spec.seed)
    fault = new_fault(spec.mode, position, np.random.default_rng([spec.seed, 7]),
                      reference=ref, span_range=cfg.span_flights, span_draw=cfg.span_draw)
    for index in range(spec.onset):
        yield from render(healthy(), index)
    for index in range(spec.onset, spec.onset + MAX_FLIGHTS):
        if fault.failed:
            yield from render(fault, index)
            return fault.threshold, index
        if (index - spec.onset) % cfg.render_every == 0:
            summ = yield from render(fault, index)
        else:
            summ = estimate_summary(aircraft, index, flight_rng(spec, index, 0),
                                    started_at=flight_start(index, day_offset=spec.day_offset),
                                    duration_s=cfg.duration_s)
        fault = advance_fault(fault, summ, flight_rng(spec, index, 1))
    return fault.threshold, None
