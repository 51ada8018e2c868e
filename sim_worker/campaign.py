"""Campaigns: design / verification sets of flight logs plus a manifest with the ground truth.

Layout: ``DIR/manifest.json`` and ``DIR/flights/<tail>/<flight>.parquet``. The manifest schema
(``ema-campaign/1``) is a contract with the PHM chain; see :func:`run_campaign`.

Determinism: every aircraft seed, pattern seed and flight seed derives from the campaign seed via
``numpy.random.SeedSequence`` with a fixed key (kind, aircraft, pattern, flight), never from the
worker that runs it; results are identical for any number of workers.

Fault-to-failure runs start with ``lead_flights`` healthy flights (the actuator's service before
the fault, every one rendered), then advance the progression law every flight from the onset;
only every ``render_every``-th flight after the onset (and the failure flight) is simulated at
12 kHz and written; the others use the quasi-static :func:`~sim_worker.flight.estimate_summary`
of the same flight conditions, fault-aware (a worn drive's measured load share), so a run's
expected life does not depend on ``render_every``.
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterator
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from server.flightlog import write_parquet
from server.vocabulary import POSITIONS, WINGLET_PAIR

from .faults import (
    A_PRIORI,
    MODES,
    PROGRESSIVE,
    FaultState,
    advance_fault,
    healthy,
    new_fault,
)
from .fleet import BASES, FLEET_BASES, Aircraft, build_aircraft
from .flight import (
    estimate_summary,
    flight_start,
    reference_summary,
    simulate_flight,
)

__all__ = ["ScaleConfig", "SCALES", "plan_campaign", "run_campaign", "FORMAT", "fleet_for"]

FORMAT = "ema-campaign/1"
_KIND_CODE = {"design": 1, "verification": 2}
_MAX_FLIGHTS = 2000


@dataclass(frozen=True)
class ScaleConfig:
    duration_s: float  # s of reference actuator activity per recording
    healthy_patterns: int  # number of healthy patterns (spread over the aircraft)
    healthy_flights: int  # flights per healthy pattern
    patterns_per_mode: int  # degradation patterns per fault mode
    render_every: int  # render every k-th flight of a fault-to-failure run
    apriori_flights: int  # flights per SE / BDO pattern
    apriori_onset: int  # index of the first faulty flight of an SE / BDO pattern
    #: healthy flights (all rendered) before a progressive fault starts: the actuator's
    #: in-service history after installation, from which detection learns its own reference
    lead_flights: int = 8


SCALES: dict[str, dict[str, ScaleConfig]] = {
    # Quick scale: big enough for honest statistics in CI (>= 250 healthy verification
    # flights on 10 aircraft, >= 3 patterns per mode), small enough for ~1 min per campaign.
    "quick": {
        "design": ScaleConfig(duration_s=60.0, healthy_patterns=10, healthy_flights=12,
                              patterns_per_mode=6, render_every=20, apriori_flights=6,
                              apriori_onset=2),
        "verification": ScaleConfig(duration_s=60.0, healthy_patterns=10, healthy_flights=25,
                                    patterns_per_mode=3, render_every=20, apriori_flights=6,
                                    apriori_onset=2),
    },
    "paper": {
        "design": ScaleConfig(duration_s=120.0, healthy_patterns=10, healthy_flights=50,
                              patterns_per_mode=10, render_every=10, apriori_flights=8,
                              apriori_onset=2),
        "verification": ScaleConfig(duration_s=120.0, healthy_patterns=25, healthy_flights=4,
                                    patterns_per_mode=25, render_every=20, apriori_flights=8,
                                    apriori_onset=2),
    },
}


def _seed(*key: int) -> int:
    return int(np.random.SeedSequence(list(key)).generate_state(1, dtype=np.uint64)[0] >> 1)


def fleet_for(kind: str, seed: int, *, bases: tuple[str, ...] | None = None,
              noise_scale: float = 1.0) -> list[Aircraft]:
    """The ten aircraft of a campaign; verification tails and seeds never equal design ones.

    ``bases`` (robustness studies) cycles the given bases over the ten aircraft instead of
    4 Turin / 3 Vancouver / 3 Abu Dhabi; ``noise_scale`` multiplies every sensor's noise
    (currents, voltages, resolver, LVDT; offsets and quantisation unchanged). Tails and
    aircraft seeds do not depend on either.
    """
    code = _KIND_CODE[kind]
    prefix = "I-DSG" if kind == "design" else "I-VER"
    order = FLEET_BASES if not bases else tuple(bases[i % len(bases)]
                                                 for i in range(len(FLEET_BASES)))
    fleet = [build_aircraft(f"{prefix}{i + 1:02d}", base, _seed(seed, code, i))
             for i, base in enumerate(order)]
    if noise_scale != 1.0:
        fleet = [_with_noise(a, noise_scale) for a in fleet]
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


def plan_campaign(kind: str, seed: int, scale: str) -> list[PatternSpec]:
    """All patterns of the campaign, in manifest order."""
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
        add("healthy", None, j % n_air, cfg.healthy_flights, 0, j)
    for m_i, mode in enumerate(MODES):
        for j in range(cfg.patterns_per_mode):
            ai = (j * 3 + m_i) % n_air
            # rod-end wear is seen only across the winglet pair, so it goes on a winglet drive
            pos = (WINGLET_PAIR[j % 2] if mode == "REWEAR"
                   else POSITIONS[(j + m_i) % len(POSITIONS)])
            if mode in A_PRIORI:
                add(mode, pos, ai, cfg.apriori_flights, cfg.apriori_onset, j)
            else:
                add(mode, pos, ai, 0, cfg.lead_flights, j)
    return specs


def _flight_rng(spec: PatternSpec, index: int, stream: int) -> np.random.Generator:
    return np.random.default_rng([spec.seed, index, stream])


def _render(out_dir: Path, aircraft: Aircraft, spec: PatternSpec, fault: FaultState, index: int,
            duration_s: float) -> tuple[str, str, Any]:
    flight_id = f"{spec.id}-{index:04d}"
    start = flight_start(index, day_offset=spec.day_offset)
    log, summary = simulate_flight(aircraft, fault, index, _flight_rng(spec, index, 0),
                                   flight_id=flight_id, started_at=start, duration_s=duration_s)
    rel = f"flights/{aircraft.tail}/{flight_id}.parquet"
    path = out_dir / rel
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    tmp.write_bytes(write_parquet(log))
    os.replace(tmp, path)
    return flight_id, rel, summary


def _flight_entry(flight_id: str, rel: str, index: int, fault: FaultState, summary: Any,
                  failure: int | None) -> dict[str, Any]:
    return {
        "flight": flight_id,
        "index": index,
        "file": rel,
        "severity": float(fault.severity) if fault.mode != "healthy" else 0.0,
        "severity_norm": float(fault.severity_norm),
        "true_rul_flights": None if failure is None else int(failure - index),
        "block_hours": float(summary.block_hours),
        "ground_temp_c": round(float(summary.ground_temp_c), 3),
        "measured_summary": {p: {k: round(v, 6) for k, v in asdict(s).items()}
                             for p, s in summary.actuators.items()},
    }


def run_pattern(args: tuple[str, str, int, ScaleConfig, PatternSpec, dict[str, Any]]
                ) -> dict[str, Any]:
    """Run one pattern (a task of the pool); returns its manifest entry."""
    out_dir_s, kind, seed, cfg, spec, options = args
    out_dir = Path(out_dir_s)
    aircraft = fleet_for(kind, seed, **options)[spec.aircraft_index]
    flights: list[dict[str, Any]] = []
    threshold: float | None = None
    failure: int | None = None
    if spec.mode == "healthy" or spec.mode in A_PRIORI:
        fault = healthy()
        if spec.mode in A_PRIORI:
            assert spec.position is not None
            fault_on = new_fault(spec.mode, spec.position, np.random.default_rng([spec.seed, 7]))
            threshold = fault_on.threshold
        for index in range(spec.n_flights):
            f = fault_on if spec.mode in A_PRIORI and index >= spec.onset else fault
            fid, rel, summ = _render(out_dir, aircraft, spec, f, index, cfg.duration_s)
            flights.append(_flight_entry(fid, rel, index, f, summ, None))
    else:
        assert spec.position is not None
        ref = reference_summary(aircraft, spec.position, duration_s=cfg.duration_s,
                                seed=spec.seed)
        fault = new_fault(spec.mode, spec.position, np.random.default_rng([spec.seed, 7]),
                          reference=ref)
        threshold = fault.threshold
        rendered: list[tuple[int, str, str, FaultState, Any]] = []
        for index in range(spec.onset):
            fid, rel, summ = _render(out_dir, aircraft, spec, healthy(), index, cfg.duration_s)
            rendered.append((index, fid, rel, healthy(), summ))
        for index in range(spec.onset, spec.onset + _MAX_FLIGHTS):
            is_fail = fault.failed
            if is_fail or (index - spec.onset) % cfg.render_every == 0:
                fid, rel, summ = _render(out_dir, aircraft, spec, fault, index, cfg.duration_s)
                rendered.append((index, fid, rel, fault, summ))
            else:
                summ = estimate_summary(aircraft, index, _flight_rng(spec, index, 0),
                                        started_at=flight_start(index, day_offset=spec.day_offset),
                                        duration_s=cfg.duration_s, fault=fault)
            if is_fail:
                failure = index
                break
            fault = advance_fault(fault, summ, _flight_rng(spec, index, 1))
        for index, fid, rel, f, summ in rendered:
            flights.append(_flight_entry(fid, rel, index, f, summ, failure))
    return {
        "id": spec.id,
        "aircraft": aircraft.tail,
        "mode": spec.mode,
        "position": spec.position,
        "threshold": threshold,
        "onset_flight": spec.onset,
        "failure_flight": failure,
        "flights": flights,
    }


def _map(tasks: list[Any], workers: int) -> Iterator[dict[str, Any]]:
    if workers <= 1:
        yield from map(run_pattern, tasks)
        return
    with ProcessPoolExecutor(max_workers=workers) as pool:
        yield from pool.map(run_pattern, tasks, chunksize=1)


def run_campaign(kind: str, out_dir: str | Path, *, seed: int, scale: str = "quick",
                 workers: int | None = None, progress: bool = True,
                 bases: tuple[str, ...] | None = None, noise_scale: float = 1.0,
                 render_every: int | None = None) -> dict[str, Any]:
    """Write a campaign and its manifest; returns the manifest.

    Manifest (``DIR/manifest.json``)::

        {"format": "ema-campaign/1", "kind", "seed", "scale",
         "aircraft": [{"tail", "base", "climate", "serials": {pos: serial}, "params": {...}}],
         "patterns": [{"id", "aircraft", "mode", "position", "threshold", "onset_flight",
                       "failure_flight", "flights": [{"flight", "index", "file", "severity",
                       "severity_norm", "true_rul_flights", "block_hours", "ground_temp_c",
                       "measured_summary"}]}]}

    ``render_every`` overrides the scale's rendering step of fault-to-failure runs (1 renders
    every flight, as a fleet in service downloads every one); the manifest records the step used.
    """
    if scale not in SCALES:
        raise ValueError(f"scale must be one of {sorted(SCALES)}")
    if bases and not set(bases) <= set(BASES):
        raise ValueError(f"bases must be among {sorted(BASES)}")
    if not noise_scale > 0:
        raise ValueError("noise_scale must be positive")
    cfg = SCALES[scale][kind]
    if render_every is not None:
        if isinstance(render_every, bool) or not isinstance(render_every, int) \
                or render_every < 1:
            raise ValueError("render_every must be a positive int")
        cfg = replace(cfg, render_every=render_every)
    from tqdm import tqdm

    from .kernel import warm_up

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    warm_up()  # compile (or load the cache) once before forking workers
    specs = plan_campaign(kind, seed, scale)
    options = {"bases": tuple(bases) if bases else None, "noise_scale": float(noise_scale)}
    fleet = fleet_for(kind, seed, **options)
    tasks = [(str(out), kind, seed, cfg, s, options) for s in specs]
    # longest tasks first improves load balance; results are re-ordered by pattern number
    order = sorted(range(len(tasks)), key=lambda i: (specs[i].mode not in PROGRESSIVE, i))
    n_workers = workers or os.cpu_count() or 1
    results: dict[int, dict[str, Any]] = {}
    bar = tqdm(total=len(tasks), desc=f"{kind} campaign", unit="pattern", disable=not progress)
    for i, res in zip(order, _map([tasks[i] for i in order], n_workers), strict=True):
        results[i] = res
        bar.update(1)
    bar.close()
    manifest = {
        "format": FORMAT,
        "kind": kind,
        "seed": int(seed),
        "scale": scale,
        "duration_s": cfg.duration_s,
        "render_every": cfg.render_every,
        "lead_flights": cfg.lead_flights,
        "noise_scale": float(noise_scale),
        "bases": list(bases) if bases else None,
        "aircraft": [{"tail": a.tail, "base": a.base, "climate": BASES[a.base],
                      "serials": dict(a.serials), "params": a.params_summary()} for a in fleet],
        "patterns": [results[i] for i in range(len(tasks))],
    }
    (out / "manifest.json").write_text(json.dumps(manifest, indent=1, sort_keys=False))
    return manifest

