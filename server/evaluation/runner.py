"""Running the whole PHM chain over a simulated campaign's patterns (paper sections 4.3 and 5).

Every pattern of the campaign is run flight by flight through
:func:`server.phm.chain.analyze_flight`
exactly as the service runs it: fresh :class:`~server.phm.chain.ActuatorHealth` for the three
actuators of the pattern's aircraft at the pattern start, state carried between flights, the
manifest's flight ``index`` passed as ``flight_index`` (fault-to-failure runs render only every
n-th flight; the particle filter propagates over the gaps). The labels of the campaign (mode,
onset, failure flight, true RUL) are read only to score the outcomes.

:func:`evaluate_campaign` runs every pattern (in worker processes when ``jobs`` > 1, each
holding the model as its JSON document) and scores the traces (:mod:`.scoring`).
"""

from __future__ import annotations

import hashlib
import json
import zlib
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from contextlib import nullcontext
from typing import Any

import numpy as np

from server.campaigns import (
    Location,
    campaign_store,
    load_campaign,
    read_manifest,
    single_fault,
)
from server.phm.chain import MeasurementHook, PhmModel, analyze_flight
from server.phm.dataset import Campaign, Pattern, reads_rod_ends_as_pair
from server.vocabulary import POSITIONS

from .bootstrap import BOOTSTRAP_SEED, CI_LEVEL, N_BOOT
from .scoring import (
    ALPHA,
    LAMBDA,
    N_PREDICTIONS,
    POINT_ESTIMATE,
    classification_summary,
    summarise_detection,
    summarise_prognosis,
    summarise_sensors,
)
from .timing import ChainTimer, feature_timing, timing_summary

Progress = Callable[[int, int], None]
#: runs the chain over one pattern: its trace (JSON-safe); a module-level function, so that
#: worker processes can be handed it
PatternRun = Callable[..., dict[str, Any]]


def pattern_seed(pattern_id: str) -> int:
    """Filter seed of a pattern: a stable hash of its id (independent of worker count)."""
    return zlib.crc32(pattern_id.encode()) & 0x7FFFFFFF


def _noise_free_hook(model: PhmModel, pattern: Pattern, severity_norm: float
                     ) -> MeasurementHook:
    """The faulty actuator's own feature (the pattern's mode's) replaced by its noise-free
    value h(true severity) of the trained measurement model; a flight without a value stays
    without, the other actuators and features are untouched."""
    spec = model.measurement[pattern.mode]
    position = str(pattern.position)
    value = float(spec.model_for(position).predict(np.array([severity_norm]))[0])

    def hook(pos: str, values: dict[str, float]) -> dict[str, float]:
        if pos != position or values.get(spec.feature) is None:
            return values
        return {**values, spec.feature: value}

    return hook


def run_pattern(model: PhmModel, pattern: Pattern, *, timer: ChainTimer | None = None,
                noise_free: bool = False) -> dict[str, Any]:
    """Run the chain over one pattern; return its per-flight trace (JSON-safe).

    Per flight: the faulty actuator's alarm, class probabilities, mode in use and RUL quantiles,
    plus the positions alarmed and newly alarmed (all three actuators are monitored).
    ``noise_free``: from the fault's onset, the prognosis of the faulty actuator sees its
    mode's own feature without noise, h(true severity) (an error budget: what is left is the
    degradation law's extrapolation; detection and classification see the real features).
    """
    health = {pos: model.new_health(pos) for pos in POSITIONS}
    seed = pattern_seed(pattern.id)
    faulty = pattern.position if pattern.mode != "healthy" else None
    budget = noise_free and faulty is not None and pattern.mode in model.measurement
    onset = int(pattern.onset_flight or 0)
    flights: list[dict[str, Any]] = []
    for rec in pattern.flights:
        hook = (_noise_free_hook(model, pattern, rec.severity_norm)
                if budget and rec.index >= onset else None)
        with timer.span("chain") if timer is not None else nullcontext():
            out = analyze_flight(model, rec.features, health, seed=seed, flight_index=rec.index,
                                 started_at=rec.started_at, base=pattern.base,
                                 measurement_hook=hook)
        o = out.get(faulty) if faulty else None
        flights.append({
            "index": rec.index,
            "severity_norm": rec.severity_norm,
            "true_rul": rec.true_rul_flights,
            "alarms": sorted(p for p, v in out.items() if v.alarm),
            "new_alarms": sorted(p for p, v in out.items() if v.new_alarm),
            # the features each new alarm was raised on, for tracing false alarms by feature
            "raised_on": {p: list(v.alarm_features) for p, v in out.items() if v.new_alarm},
            # the units each new alarm named at raising, with their probabilities (isolation)
            "isolation": {p: dict(v.isolation) for p, v in out.items() if v.new_alarm},
            "alarm": bool(o.alarm) if o is not None else None,
            "probs": dict(o.class_probabilities) if o is not None and o.class_probabilities
            else None,
            "fault_mode": o.fault_mode if o is not None else None,
            # the modes present and each mode's own probability (a second mode named beside
            # a single fault is scored by bench/mode_sets.py)
            "modes": list(o.modes) if o is not None and o.modes else None,
            "own": o.mode_probabilities if o is not None else None,
            "own_features": dict(o.own_features) if o is not None and o.own_features
            else None,
            "rul": o.rul.to_dict() if o is not None and o.rul is not None else None,
            "sensor": sorted({f"{x['channel']} {x['metric']}" for v in out.values()
                              for x in v.sensor_findings}),
        })
    return {"id": pattern.id, "aircraft": pattern.aircraft, "mode": pattern.mode,
            "position": pattern.position, "onset": pattern.onset_flight,
            "failure": pattern.failure_flight, "seed": seed,
            "pair_rod_ends": reads_rod_ends_as_pair(pattern),
            "horizon": float(model.prognoser.max_horizon_flights), "flights": flights}


_WORKER_MODEL: PhmModel | None = None
_WORKER_NOISE_FREE = False
_WORKER_RUN: PatternRun = run_pattern


def _init_worker(model_doc: dict[str, Any], noise_free: bool = False,
                 run: PatternRun = run_pattern) -> None:
    global _WORKER_MODEL, _WORKER_NOISE_FREE, _WORKER_RUN
    _WORKER_MODEL = PhmModel.from_dict(model_doc)
    _WORKER_NOISE_FREE = noise_free
    _WORKER_RUN = run


def _work(pattern: Pattern) -> tuple[dict[str, Any], dict[str, Any]]:
    if _WORKER_MODEL is None:
        raise RuntimeError("the evaluation worker has no model: _init_worker was not run")
    timer = ChainTimer()
    with timer.instrument():
        trace = _WORKER_RUN(_WORKER_MODEL, pattern, timer=timer, noise_free=_WORKER_NOISE_FREE)
    return trace, timer.to_dict()


def evaluate_patterns(model: PhmModel, patterns: Sequence[Pattern], *, jobs: int = 1,
                      progress: Progress | None = None, noise_free: bool = False,
                      run: PatternRun = run_pattern
                      ) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """Traces of all patterns (in the given order) and the merged chain timings.

    The model goes to the workers as its JSON document (and is rebuilt from it in the serial
    case too), so the results do not depend on ``jobs``. ``noise_free``: see
    :func:`run_pattern`. ``run``: what runs one pattern (:func:`run_pattern`; a concurrent
    campaign's, :func:`.concurrent.run_concurrent_pattern`).
    """
    doc = model.to_dict()
    order = sorted(range(len(patterns)), key=lambda i: -len(patterns[i].flights))
    results: dict[int, tuple[dict[str, Any], dict[str, Any]]] = {}
    if jobs <= 1:
        _init_worker(doc, noise_free, run)
        for k, i in enumerate(order):
            results[i] = _work(patterns[i])
            if progress is not None:
                progress(k + 1, len(patterns))
    else:
        with ProcessPoolExecutor(max_workers=jobs, initializer=_init_worker,
                                 initargs=(doc, noise_free, run)) as ex:
            futs = {ex.submit(_work, patterns[i]): i for i in order}
            for k, fut in enumerate(as_completed(futs)):
                results[futs[fut]] = fut.result()
                if progress is not None:
                    progress(k + 1, len(patterns))
    traces = [results[i][0] for i in range(len(patterns))]
    timing = ChainTimer.merge([results[i][1] for i in range(len(patterns))])
    return traces, timing


def evaluate_campaign(model: PhmModel, campaign_dir: Location, *, jobs: int = 1,
                      progress: Progress | None = None, timing_flights: int = 6,
                      campaign: Campaign | None = None,
                      point_estimate: str = POINT_ESTIMATE,
                      noise_free: bool = False) -> dict[str, Any]:
    """Run the chain over every pattern of a campaign and score it (JSON-safe dict).

    ``timing_flights`` flights are re-read and their features recomputed (serially) to time
    feature extraction; 0 skips that measurement. ``point_estimate``: the RUL the prognostic
    metrics score, "median" or "mode". ``noise_free``: the prognosis sees noise-free own
    features (an error budget, :func:`run_pattern`). A concurrent-fault campaign is refused
    (:func:`~server.campaigns.single_fault`).
    """
    root = campaign_store(campaign_dir)  # a directory or s3://bucket/prefix
    single_fault(read_manifest(root), str(root), "the evaluation")
    camp = campaign or load_campaign(root, jobs=max(jobs, 1))
    traces, chain_timing = evaluate_patterns(model, camp.patterns, jobs=jobs, progress=progress,
                                             noise_free=noise_free)
    classes = ([str(c) for c in model.classifier.classes_.tolist()]
               if model.classifier is not None else [])
    feat = feature_timing(root, n_flights=timing_flights) if timing_flights > 0 else None
    manifest = read_manifest(root)
    return {
        "format": "ema-evaluation/1",
        "campaign": {"dir": str(root), "kind": camp.kind, "seed": camp.seed,
                     "scale": manifest.get("scale"), "render_every": manifest.get("render_every"),
                     "duration_s": manifest.get("duration_s"),
                     "patterns": len(camp.patterns), "partial": manifest.get("partial"),
                     "flights": sum(len(p.flights) for p in camp.patterns),
                     "aircraft": [{"tail": a.get("tail"), "base": a.get("base"),
                                   "climate": a.get("climate")} for a in camp.aircraft]},
        "model": model_identity(model),
        "settings": {"alpha": ALPHA, "lambda": LAMBDA, "n_predictions": N_PREDICTIONS,
                     "point_estimate": point_estimate, "ph_normalisation": "failure - onset",
                     "ph": "Saxena: every later point estimate within true RUL +- alpha x life",
                     "ph_cone": "every later point estimate within (1 +- alpha) x true RUL",
                     "prognosis_features": "noise-free h(true severity)" if noise_free
                     else "measured",
                     "cra_weights": "1..n (growing toward end of life)",
                     "convergence_axis": "(t - onset) / life",
                     "calibration": "true RUL within q25..q75 (central_50) and q05..q95 "
                                    "(central_90) of the RUL distribution at the selected "
                                    "predictions; none counts as a miss; width_*_flights: "
                                    "mean width of those intervals where finite",
                     "bootstrap": {"resamples": N_BOOT, "level": CI_LEVEL,
                                   "seed": BOOTSTRAP_SEED, "unit": "pattern",
                                   "interval": "percentile"},
                     "jobs": jobs},
        "detection": summarise_detection(traces, model.detector.false_alarm_rate),
        "classification": classification_summary(traces, classes),
        "prognosis": summarise_prognosis(traces, point_estimate=point_estimate),
        "sensors": summarise_sensors(traces),
        "timing": timing_summary(chain_timing, feat, model),
        "patterns": traces,
    }


def model_identity(model: PhmModel) -> dict[str, Any]:
    """Format and SHA-256 of the model's JSON document (keys sorted): which model was scored."""
    doc = model.to_dict()
    text = json.dumps(doc, sort_keys=True, default=lambda o: o.tolist()
                      if hasattr(o, "tolist") else str(o))
    return {"format": doc.get("format"),
            "sha256": hashlib.sha256(text.encode()).hexdigest()}
