"""Does the test station honour the time to failure an operator asks for?

``sim-worker span-check`` flies test-station injections the way ``sim-worker run`` does
(:func:`~sim_worker.steering.plan_fault` at the start, every flight simulated at 12 kHz with
the runner's recording length, :func:`~sim_worker.steering.steer_and_advance` after it) without
a service, and records for each one the requested span and the flights it really took from its
start to the first flight at failure. ``--fixed-rate`` flies the same injections with the rate
fixed at onset (no steering), for comparison.

Injections cycle over the fleet's aircraft (three bases) and positions (REWEAR on the winglet
only), start on flights spread over a year (every season), and request spans drawn from
``--span-range``.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from server.vocabulary import POSITIONS, PROGRESSIVE

from .faults import advance_fault
from .flight import flight_start, reference_summary, simulate_flight
from .service import fleet_plan
from .steering import plan_fault, steer_and_advance

__all__ = ["SpanCase", "span_cases", "fly_case", "check_spans", "summarise"]

_N_AIRCRAFT = 10
_WINGLET = ("WL1", "WL2")


@dataclass(frozen=True)
class SpanCase:
    mode: str
    index: int  # within the mode
    aircraft: int  # index into the fleet plan
    position: str
    start_flight: int
    span: int  # requested flights from start to failure


def span_cases(per_mode: int, seed: int, span_range: tuple[int, int],
               modes: tuple[str, ...] = PROGRESSIVE) -> list[SpanCase]:
    rng = np.random.default_rng([seed, 31])
    cases = []
    for mode in modes:
        positions = _WINGLET if mode == "REWEAR" else POSITIONS
        for i in range(per_mode):
            cases.append(SpanCase(mode, i, aircraft=i % _N_AIRCRAFT,
                                  position=positions[i % len(positions)],
                                  start_flight=1 + int(rng.integers(0, 730)),
                                  span=int(rng.integers(span_range[0], span_range[1] + 1))))
    return cases


def fly_case(case: SpanCase, *, seed: int, duration_s: float, steered: bool = True
             ) -> dict[str, Any]:
    """Fly one injection to failure (or to 3 x its span); the flights it took."""
    aircraft = fleet_plan(_N_AIRCRAFT, seed)[case.aircraft]
    rng = np.random.default_rng([seed, 41, hash_case(case)])
    reference = reference_summary(aircraft, case.position, duration_s=duration_s,
                                  seed=(seed, 12, case.aircraft))
    fault, plan = plan_fault(case.mode, case.position, rng, reference=reference,
                             start_flight=case.start_flight, span_flights=float(case.span),
                             base=aircraft.base)
    n = case.start_flight
    while not fault.failed and n < case.start_flight + 3 * case.span:
        flight_rng = np.random.default_rng([seed, 13, hash_case(case), n])
        _, summary = simulate_flight(aircraft, fault, n, flight_rng,
                                     started_at=flight_start(n), duration_s=duration_s)
        grow_rng = np.random.default_rng([seed, 14, hash_case(case), n])
        if steered and plan is not None:
            plan = steer_and_advance(plan, summary, n, grow_rng)
            fault = plan.state
        else:
            fault = advance_fault(fault, summary, grow_rng)
        n += 1
    took = n - case.start_flight if fault.failed else None
    return {"mode": case.mode, "index": case.index, "aircraft": aircraft.tail,
            "base": aircraft.base, "position": case.position, "start_flight": case.start_flight,
            "requested": case.span, "took": took, "steered": steered,
            "error": None if took is None else took / case.span - 1.0}


def hash_case(case: SpanCase) -> int:
    return PROGRESSIVE.index(case.mode) * 1000 + case.index


def _fly(args: tuple[SpanCase, int, float, bool]) -> dict[str, Any]:
    case, seed, duration_s, steered = args
    return fly_case(case, seed=seed, duration_s=duration_s, steered=steered)


def check_spans(cases: list[SpanCase], *, seed: int, duration_s: float, steered: bool,
                workers: int = 1) -> Iterator[dict[str, Any]]:
    """Each case's record, in the order they finish (sorted by the caller)."""
    jobs = [(c, seed, duration_s, steered) for c in cases]
    if workers <= 1:
        yield from map(_fly, jobs)
        return
    with ProcessPoolExecutor(workers) as pool:
        yield from pool.map(_fly, jobs)


def summarise(records: list[dict[str, Any]]) -> dict[str, dict[str, Any]]:
    """Per mode: injections, the share within 10 % of the requested span, the mean and the
    largest relative error, and how many never failed within 3 x the span."""
    out = {}
    for mode in PROGRESSIVE:
        rows = [r for r in records if r["mode"] == mode]
        if not rows:
            continue
        err = np.array([r["error"] for r in rows if r["error"] is not None])
        out[mode] = {"injections": len(rows),
                     "within_10pct": float(np.mean(np.abs(err) <= 0.10)) if err.size else 0.0,
                     "mean_error": float(np.mean(err)) if err.size else None,
                     "max_abs_error": float(np.max(np.abs(err))) if err.size else None,
                     "not_failed": len(rows) - int(err.size)}
    return out


def write_report(path: str | Path, records: list[dict[str, Any]], settings: dict[str, Any]
                 ) -> dict[str, Any]:
    records = sorted(records, key=lambda r: (PROGRESSIVE.index(r["mode"]), r["index"]))
    doc = {"format": "ema-span-check/1", "settings": settings,
           "summary": summarise(records), "injections": records}
    Path(path).write_text(json.dumps(doc, indent=1) + "\n")
    return doc
