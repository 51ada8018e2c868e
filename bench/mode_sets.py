"""Choose the mode-set threshold, on design seeds' evaluations.

A unit in alarm names its leading mode and every other mode whose own probability is at the
threshold or above (:mod:`server.phm.classification.modes`). Every evaluation keeps, per flight
in alarm, the leading mode and each mode's own probability, so each threshold is scored from
the stored traces in seconds, without running the chain again:

- on concurrent evaluations (``concurrent.json``, ``hmsm evaluate`` on a concurrent campaign):
  both modes named on the flight of the first fault's half life (:mod:`server.evaluation.
  concurrent_scoring`), and the unit-flights naming a mode their unit does not carry;
- on single-fault evaluations (``evaluation.json``): the faulty unit's flights in alarm that
  name a second mode (a fault it does not carry).

The choice: the highest threshold whose share named at half life is at or above ``--target``
(0.90) while at most ``--spurious`` (0.05) of the unit-flights in alarm name a mode their unit
does not carry, on single faults and on concurrent ones alike (a false claim either way).
Without one (the target not met at any threshold: the grid says by how much), among the
thresholds within that limit, those naming the most faults, and of them the one naming the
fewest modes a unit does not carry (ties: the highest).

    python bench/mode_sets.py --concurrent C.json [C.json ...] --single E.json [E.json ...]
        [--target 0.9] [--spurious 0.05] [--out F.json]

With ``--crosstalk CT.json`` (``bench/mode_crosstalk.py``: the design's cross-talk limits at
each quantile of a grid) the grid is over the quantile instead, at the service's threshold
(``MODE_SET``), and "none" (no limits) beside it: a mode also joins when its own feature,
pooled since the alarm (kept in the traces), is beyond the leading mode's limit. The choice is
the same rule with the quantile in the threshold's place (the highest, the most conservative,
that meets the target; no limits ranking above every quantile).

Score the chosen threshold on a concurrent verification campaign once, with ``hmsm evaluate``
(the service's rule is ``MODE_SET``).
"""

from __future__ import annotations

import argparse
import copy
import json
from pathlib import Path
from typing import Any

from server.evaluation.concurrent_scoring import score_concurrent
from server.phm.classification.crosstalk import CrossTalk
from server.phm.classification.modes import MODE_SET, ModeSetRule, modes_present
from server.phm.metrics import proportion_interval

THRESHOLDS = (0.05, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9)


def _load(paths: list[Path]) -> list[dict[str, Any]]:
    """The traces of evaluations (concurrent.json or evaluation.json)."""
    return [t for p in paths for t in json.loads(p.read_text())["patterns"]]


def _named(unit: dict[str, Any], rule: ModeSetRule, crosstalk: CrossTalk | None) -> list[str]:
    """A unit-flight's modes present under ``rule`` and the cross-talk limits."""
    lead = unit["fault_mode"]
    beyond = ([] if crosstalk is None
              else crosstalk.beyond(lead, unit.get("own_features") or {}))
    return modes_present(lead, unit["own"], rule, beyond)


def _with_rule(traces: list[dict[str, Any]], rule: ModeSetRule,
               crosstalk: CrossTalk | None = None) -> list[dict[str, Any]]:
    """The concurrent traces with every unit's modes recomputed under ``rule``."""
    out = copy.deepcopy(traces)
    for t in out:
        for f in t["flights"]:
            for unit in f["units"].values():
                if unit.get("own") and unit.get("fault_mode"):
                    unit["modes"] = _named(unit, rule, crosstalk)
    return out


def _single_spurious(traces: list[dict[str, Any]], rule: ModeSetRule,
                     crosstalk: CrossTalk | None = None) -> dict[str, Any]:
    """Flights in alarm of a single fault's unit naming a mode beside its own."""
    wrong = total = 0
    for t in traces:
        if t["mode"] == "healthy":
            continue
        for f in t["flights"]:
            if f["alarm"] and f.get("own") and f.get("fault_mode"):
                total += 1
                wrong += any(m != t["mode"] for m in _named(f, rule, crosstalk)[1:])
    return {"hits": wrong, "n": total, "share": wrong / total if total else None,
            "interval": proportion_interval(wrong, total) if total else None}


def _row(concurrent: list[dict[str, Any]], single: list[dict[str, Any]], rule: ModeSetRule,
         crosstalk: CrossTalk | None) -> dict[str, Any]:
    s = score_concurrent(_with_rule(concurrent, rule, crosstalk))["all"]
    return {"threshold": rule.threshold, "named_at_half": s["named_at_half"],
            "faults_named": s["faults_named"], "concurrent_spurious": s["spurious"],
            "single_spurious": _single_spurious(single, rule, crosstalk)}


def grid(concurrent: list[dict[str, Any]], single: list[dict[str, Any]]) -> list[dict[str, Any]]:
    return [_row(concurrent, single, ModeSetRule(t), None) for t in THRESHOLDS]


def crosstalk_grid(concurrent: list[dict[str, Any]], single: list[dict[str, Any]],
                   fits: dict[str, Any]) -> list[dict[str, Any]]:
    """At the service's threshold: no limits, then the limits at each quantile of ``fits``."""
    rows = [{**_row(concurrent, single, MODE_SET, None), "quantile": None}]
    for q, fit in sorted(fits.items(), key=lambda kv: -float(kv[0])):
        rows.append({**_row(concurrent, single, MODE_SET, CrossTalk.from_dict(fit)),
                     "quantile": float(q)})
    return rows


def choose(rows: list[dict[str, Any]], target: float, spurious: float
           ) -> tuple[dict[str, Any] | None, bool]:
    """The chosen row and whether it meets the target (see the module docstring)."""
    within = [r for r in rows if (r["single_spurious"]["share"] or 0.0) <= spurious
              and (r["concurrent_spurious"]["share"] or 0.0) <= spurious]
    ok = [r for r in within if (r["named_at_half"]["share"] or 0.0) >= target]
    if ok:
        return max(ok, key=lambda r: r["threshold"]), True
    if not within:
        return None, False
    most = max(r["faults_named"]["hits"] for r in within)
    return min((r for r in within if r["faults_named"]["hits"] == most),
               key=lambda r: (r["concurrent_spurious"]["hits"], -r["threshold"])), False


def _label(row: dict[str, Any]) -> str:
    if "quantile" in row:
        return "no cross-talk limits" if row["quantile"] is None else f"quantile {row['quantile']}"
    return f"threshold {row['threshold']:.2f}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--concurrent", nargs="+", type=Path, required=True)
    ap.add_argument("--single", nargs="+", type=Path, required=True)
    ap.add_argument("--target", type=float, default=0.9)
    ap.add_argument("--spurious", type=float, default=0.05)
    ap.add_argument("--crosstalk", type=Path,
                    help="the design's cross-talk limits per quantile (bench/mode_crosstalk.py):"
                         " grid over the quantile at the service's threshold")
    ap.add_argument("--out", type=Path)
    args = ap.parse_args()
    concurrent, single = _load(args.concurrent), _load(args.single)
    if args.crosstalk:
        fits = json.loads(args.crosstalk.read_text())["fits"]
        rows = crosstalk_grid(concurrent, single, fits)
        # the choice below ranks by "threshold", the most conservative highest: the quantile,
        # no limits above every quantile
        for r in rows:
            r["threshold"] = 2.0 if r["quantile"] is None else r["quantile"]
    else:
        rows = grid(concurrent, single)
    for r in rows:
        h, c, s = r["named_at_half"], r["concurrent_spurious"], r["single_spurious"]
        print(f"{_label(r)}: named at half {h['hits']}/{h['n']}, "
              f"faults named {r['faults_named']['hits']}/{r['faults_named']['n']}, "
              f"spurious concurrent {c['hits']}/{c['n']}, single {s['hits']}/{s['n']}")
    chosen, met = choose(rows, args.target, args.spurious)
    print("chosen:", None if chosen is None else _label(chosen),
          "(target met)" if met else "(target not met at any threshold)")
    if args.out:
        args.out.write_text(json.dumps({"target": args.target, "spurious": args.spurious,
                                        "grid": rows, "chosen": chosen, "target_met": met},
                                       indent=1) + "\n")


if __name__ == "__main__":
    main()
