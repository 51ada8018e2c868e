"""A concurrent pattern's run: two progressive faults on one aircraft, each from its own onset
by its own law (:func:`concurrent_run`), and its ground truth per fault.

Every flight carries the faults progressing on it (both of one actuator's in its parameter
row at once, :func:`~sim_worker.faults.merged_entries`); after the flight each advances by
itself from the flight's summary, on its own random stream. When a fault reaches its
threshold its actuator has failed: that flight (its failure flight) is flown and rendered with
every fault on the actuator, which is then replaced (a new serial, the same unit parameters)
and every fault on it ends: the one that failed, and a second one censored (it never reached
its threshold: no failure flight, no true RUL). A fault on the other actuator flies on. The
pattern ends once every fault has started and none is progressing (or ``MAX_FLIGHTS`` after
the first onset). The healthy lead is rendered, then every ``render_every``-th flight from the
first onset and every failure flight; the others use the estimated summary, as single-fault
runs do.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Generator
from dataclasses import dataclass, field, replace
from typing import Any, Protocol

import numpy as np

from server.flightlog import FlightLog

from ..faults import (
    THRESHOLDS,
    Faults,
    FaultState,
    FlightSummary,
    advance_fault,
    healthy,
    new_fault,
)
from ..fleet import Aircraft
from ..flight import FlightSpec, estimate_summary, flight_start, reference_summary
from .planning import PatternSpec, PlannedFault, flight_rng
from .scales import MAX_FLIGHTS, ScaleConfig

__all__ = ["Track", "ConcurrentRun", "concurrent_run", "fault_truths", "pattern_faults"]

#: a rendered flight of a pattern: yields its spec, returns its summary
_Rendered = Generator[FlightSpec, tuple[FlightLog, FlightSummary], Any]
#: the random stream of fault ``k``'s progression on a flight is ``_ADVANCE_STREAM + k``
#: (a single-fault run's is 1; streams 0 and 5 are the flight's and its recording's)
_ADVANCE_STREAM = 10


class Render(Protocol):
    """Renders one flight of the pattern with ``fault`` (here a tuple of faults) on ``units``
    (the aircraft as it is then: replaced units have new serials)."""

    def __call__(self, fault: Faults, index: int, units: Aircraft) -> _Rendered: ...


@dataclass
class Track:
    """One fault of the pattern as it flies: not started (``state`` None), progressing, or
    ended (``end``: the flight its actuator failed on; ``failure``: that flight too when it
    was this fault that reached its threshold, else None: censored)."""

    plan: PlannedFault
    state: FaultState | None = None
    end: int | None = None
    failure: int | None = None

    @property
    def progressing(self) -> bool:
        return self.state is not None and self.end is None


@dataclass
class ConcurrentRun:
    """What a concurrent pattern flew: its faults' tracks, and per rendered flight the state
    of each fault on it as the flight began (by track number)."""

    tracks: list[Track]
    flown: dict[int, dict[int, FaultState]] = field(default_factory=dict)


def _start(tracks: list[Track], index: int, spec: PatternSpec, aircraft: Aircraft,
           cfg: ScaleConfig) -> None:
    """Start the faults whose onset is flight ``index``, each at its planned span (its rate
    set against its actuator's average flight)."""
    for k, t in enumerate(tracks):
        if t.plan.onset != index or t.end is not None:
            continue
        ref = reference_summary(aircraft, t.plan.position, duration_s=cfg.duration_s,
                                seed=spec.seed)
        t.state = new_fault(t.plan.mode, t.plan.position,
                            np.random.default_rng([spec.seed, 7, k]), reference=ref,
                            span_flights=t.plan.span_flights)


def _replaced(units: Aircraft, position: str, serial: str) -> Aircraft:
    """The aircraft after the unit at ``position`` was replaced by the unit ``serial`` (the
    same unit parameters: the simulated fleet's units differ by their build, not their age)."""
    return replace(units, serials={**units.serials, position: serial})


def _end_at(tracks: list[Track], positions: set[str], index: int) -> None:
    """Every fault on a failed actuator ends at its failure flight ``index`` (those not yet
    started too: they will not start on the new unit); the one at its threshold failed."""
    for t in tracks:
        if t.plan.position in positions and t.end is None:
            t.end = index
            if t.state is not None and t.state.failed:
                t.failure = index


def concurrent_run(aircraft: Aircraft, spec: PatternSpec, cfg: ScaleConfig, render: Render
                   ) -> Generator[FlightSpec, tuple[FlightLog, FlightSummary], ConcurrentRun]:
    """The pattern's flights (see the module docstring); returns what it flew."""
    run = ConcurrentRun([Track(p) for p in spec.faults])
    tracks, units, replacements = run.tracks, aircraft, Counter[str]()
    first = min(p.onset for p in spec.faults)
    for index in range(first + MAX_FLIGHTS):
        _start(tracks, index, spec, aircraft, cfg)
        states = {k: t.state for k, t in enumerate(tracks) if t.progressing and t.state}
        if not states and all(t.state is not None or t.end is not None for t in tracks):
            break  # every fault started has ended
        failing = {str(s.position) for s in states.values() if s.failed}
        if index < first or failing or (index - first) % cfg.render_every == 0:
            run.flown[index] = states
            summ = yield from render(tuple(states.values()) or healthy(), index, units)
        else:
            summ = estimate_summary(units, index, flight_rng(spec, index, 0),
                                    started_at=flight_start(index, day_offset=spec.day_offset),
                                    duration_s=cfg.duration_s)
        _end_at(tracks, failing, index)
        for k, state in states.items():
            if tracks[k].end is None:  # each by its own law, on its own stream
                tracks[k].state = advance_fault(state, summ,
                                                flight_rng(spec, index, _ADVANCE_STREAM + k))
        for pos in sorted(failing):
            replacements[pos] += 1
            units = _replaced(units, pos, f"{aircraft.serials[pos]}-R{replacements[pos]}")
    return run


def fault_truths(run: ConcurrentRun, index: int) -> list[dict[str, Any]]:
    """Each fault's truth on rendered flight ``index``: its state as the flight began, its
    true RUL and failure flight (None for a censored or unfinished fault: never known)."""
    out = []
    for k, state in run.flown[index].items():
        failure = run.tracks[k].failure
        out.append({"mode": state.mode, "position": state.position,
                    "severity": float(state.severity),
                    "severity_norm": float(state.severity_norm),
                    "true_rul_flights": None if failure is None else int(failure - index),
                    "failure_flight": failure})
    return out


def pattern_faults(run: ConcurrentRun) -> list[dict[str, Any]]:
    """Each fault of the pattern as planned and as it ended: ``outcome`` "failed" (it reached
    its threshold), "censored" (its actuator failed of the other fault first: its severity
    fraction then, no failure flight) or "unfinished" (still progressing at ``MAX_FLIGHTS``)."""
    out = []
    for t in run.tracks:
        state = t.state
        outcome = ("failed" if t.failure is not None else
                   "unfinished" if t.end is None else "censored")
        out.append({"mode": t.plan.mode, "position": t.plan.position,
                    "threshold": THRESHOLDS[t.plan.mode],
                    "onset_flight": t.plan.onset,
                    "span_flights": round(t.plan.span_flights, 3),
                    "expected_failure_flight": t.plan.onset + round(t.plan.span_flights),
                    "started": state is not None,
                    "outcome": outcome, "end_flight": t.end, "failure_flight": t.failure,
                    "severity_norm_at_end": None if state is None
                    else float(state.severity_norm)})
    return out

