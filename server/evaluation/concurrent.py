"""The chain over a concurrent campaign: two faults per pattern, on one actuator or two.

Every pattern is run flight by flight through :func:`server.phm.chain.analyze_flight` as a
single-fault pattern is (:mod:`.runner`), but its trace keeps what every unit in alarm said on
each flight: the leading mode, the modes present (the leading one and every other at the
mode-set threshold, :mod:`server.phm.classification.modes`), each mode's own probability and
the RUL. The campaign's truth per fault (its unit, onset, failure or censoring) is read from
the manifest only to score the traces (:mod:`.concurrent_scoring`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from contextlib import nullcontext
from typing import Any

from server.campaigns import Location, campaign_store, load_campaign, read_manifest
from server.phm.chain import ActuatorOutcome, PhmModel, analyze_flight
from server.phm.dataset import Pattern
from server.vocabulary import POSITIONS

from .concurrent_scoring import score_concurrent
from .runner import evaluate_patterns, model_identity, pattern_seed
from .timing import ChainTimer

__all__ = ["run_concurrent_pattern", "evaluate_concurrent", "concurrent_markdown"]


def _unit(o: ActuatorOutcome) -> dict[str, Any]:
    return {"new_alarm": o.new_alarm, "probs": o.class_probabilities,
            "fault_mode": o.fault_mode, "modes": list(o.modes), "own": o.mode_probabilities,
            "own_features": dict(o.own_features) or None,
            "confirmed": o.confirmed, "confirmed_others": list(o.confirmed_others),
            "isolation": dict(o.isolation) if o.new_alarm else None,
            "rul": None if o.rul is None else o.rul.to_dict()}


def run_concurrent_pattern(model: PhmModel, pattern: Pattern, *,
                           timer: ChainTimer | None = None, noise_free: bool = False
                           ) -> dict[str, Any]:
    """Run the chain over one concurrent pattern: per flight, each unit in alarm's outcome
    (``units``). ``noise_free`` is refused: the error budget reads one fault's severity."""
    if noise_free:
        raise ValueError("noise-free features are a single-fault error budget")
    health = {pos: model.new_health(pos) for pos in POSITIONS}
    seed = pattern_seed(pattern.id)
    flights = []
    for rec in pattern.flights:
        with timer.span("chain") if timer is not None else nullcontext():
            out = analyze_flight(model, rec.features, health, seed=seed, flight_index=rec.index,
                                 started_at=rec.started_at, base=pattern.base)
        flights.append({"index": rec.index,
                        "units": {p: _unit(o) for p, o in out.items() if o.alarm}})
    return {"id": pattern.id, "aircraft": pattern.aircraft, "combination": pattern.mode,
            "seed": seed, "horizon": float(model.prognoser.max_horizon_flights),
            "flights": flights}


def _truths(manifest: Mapping[str, Any]) -> dict[str, dict[str, Any]]:
    """Per pattern id: its faults as planned and ended, and each rendered flight's faults."""
    return {str(p["id"]): {"faults": p["faults"],
                           "flights": [{"index": int(f["index"]), "faults": f.get("faults") or []}
                                       for f in p["flights"]]}
            for p in manifest["patterns"]}


def evaluate_concurrent(model: PhmModel, campaign_dir: Location, *, jobs: int = 1,
                        progress: Callable[[int, int], None] | None = None) -> dict[str, Any]:
    """Run the chain over every pattern of a concurrent campaign and score it (JSON-safe)."""
    root = campaign_store(campaign_dir)
    manifest = read_manifest(root)
    if manifest.get("kind") != "concurrent":
        raise ValueError(f"{root} is a {manifest.get('kind')} campaign, not a concurrent one")
    camp = load_campaign(root, jobs=max(jobs, 1))
    traces, _ = evaluate_patterns(model, camp.patterns, jobs=jobs, progress=progress,
                                  run=run_concurrent_pattern)
    truths = _truths(manifest)
    for t in traces:
        t["truth"] = truths[t["id"]]
    return {"format": "ema-concurrent-evaluation/1",
            "campaign": {"dir": str(root), "kind": "concurrent", "seed": camp.seed,
                         "scale": manifest.get("scale"), "patterns": len(camp.patterns),
                         "partial": manifest.get("partial"),
                         "flights": sum(len(p.flights) for p in camp.patterns)},
            "model": model_identity(model),
            "summary": score_concurrent(traces),
            "patterns": traces}


def _share(s: Mapping[str, Any]) -> str:
    if not s["n"]:
        return "-"
    lo, hi = s["interval"]
    return f"{s['hits']}/{s['n']} [{100 * lo:.0f}, {100 * hi:.0f}] %"


def _mean(e: Mapping[str, Any], key: str, scale: float = 1.0) -> str:
    if e[key] is None:
        return "-"
    ci = e.get(f"{key}_ci") or [math.nan, math.nan]
    return f"{scale * e[key]:.2f} [{scale * ci[0]:.2f}, {scale * ci[1]:.2f}]"


def concurrent_markdown(summary: Mapping[str, Any]) -> str:
    """The concurrent table: per combination kind and over all, each share with its exact
    interval, the earlier failure's PH and RA with bootstrap intervals."""
    head = ("| combination | patterns | faults alarmed | faults named | faults confirmed | both "
            "named by the first's half life | still named at it | second after it | earlier "
            "failure: PH | PH cone | RA [%] | spurious modes (unit-flights) | spurious "
            "confirmations |\n" + "|---" * 13 + "|")
    rows = [*summary["combinations"].items(), ("all", summary["all"])]
    lines = [f"| {name} | {s['patterns']} | {_share(s['faults_alarmed'])} | "
             f"{_share(s['faults_named'])} | {_share(s['faults_confirmed'])} | "
             f"{_share(s['named_by_half'])} | {_share(s['named_at_half'])} | "
             f"{s['second_after_half']} | {_mean(s['earlier_failure'], 'ph')} | "
             f"{_mean(s['earlier_failure'], 'ph_cone')} | "
             f"{_mean(s['earlier_failure'], 'ra', 100.0)} | {_share(s['spurious'])} | "
             f"{_share(s['spurious_confirmations']) if 'spurious_confirmations' in s else '-'} |"
             for name, s in rows]
    modes = ["", "| earlier failure's mode | patterns | PH (Saxena) | RA [%] |",
             "|---|---|---|---|"]
    modes += [f"| {m} | {e['n']} | {_mean(e, 'ph')} | {_mean(e, 'ra', 100.0)} |"
              for m, e in summary.get("earlier_failure_by_mode", {}).items()]
    return "\n".join([head, *lines, *modes])
