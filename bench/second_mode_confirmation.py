"""Choose how many flights a mode named by its own feature must stay beyond the leading mode's
cross-talk before it is confirmed present, on concurrent design campaigns' evaluations.

A second mode is confirmed (:func:`server.phm.classification.confirmation.advance_others`)
when it has stood in the set on the rule's flights in a row with its own probability at the
rule's on the last, or on its ``feature_flights`` in a row with its own feature beyond the
leader's cross-talk on the last. The traces of ``hmsm evaluate`` on a concurrent campaign
keep, per flight and unit in alarm, the modes present, their own probabilities and pooled own
features, so each run length of the feature path is replayed from them in seconds (the
probability path stays the service's ``CONFIRMATION``; the last row has no feature path, the
rule before it). For every run length: the faults confirmed on their unit by their end, the
confirmations beside the leading mode of a mode the unit does not carry on that flight
(spurious) and the flights from a fault's naming to its confirmation. The choice: the fewest
mean flights among the run lengths that confirm every fault with no more spurious
confirmations than the rule without the feature path.

    python bench/second_mode_confirmation.py --model MODEL.json EVAL_DIR [EVAL_DIR ...] \\
        [--out F.json]

On traces of the service's own run length, the replay confirms on the same flights as the
chain (the column "as the traces"), so the replay is the chain's rule, not a copy of it.
"""

from __future__ import annotations

import argparse
import json
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from server.evaluation.concurrent_scoring import score_pattern
from server.phm.chain.model import read_model_document
from server.phm.classification.confirmation import CONFIRMATION, advance_others
from server.phm.classification.crosstalk import CrossTalk
from server.phm.metrics import proportion_interval
from server.vocabulary import POSITIONS

RUN_LENGTHS = (1, 2, 3, 4, 6, 8, 12, 10**6)  # the last: no feature path (the rule before)


def _traces(dirs: list[Path]) -> list[dict[str, Any]]:
    out = []
    for d in dirs:
        doc = json.loads((d / "concurrent.json").read_text(encoding="utf-8"))
        out += doc["patterns"]
    return out


def _unit_confirmations(trace: dict[str, Any], pos: str, crosstalk: CrossTalk,
                        feature_flights: int) -> list[tuple[int, str, bool]]:
    """(flight, mode, the chain confirmed it there too) of each mode confirmed beside the
    leading one on ``pos``, replayed with the feature path's run length."""
    rule = replace(CONFIRMATION, feature_flights=feature_flights)
    runs: dict[str, int] = {}
    done: set[str] = set()
    out = []
    for f in trace["flights"]:
        u = f["units"].get(pos)
        if u is None or not u.get("probs"):
            continue
        if u["new_alarm"]:
            runs, done = {}, set()
        if u.get("confirmed"):
            done.add(u["confirmed"])
        modes, own = u["modes"], u.get("own") or {}
        beyond = crosstalk.beyond(modes[0], u["own_features"] or {})
        runs, held = advance_others(rule, runs, modes, own, beyond)
        for m in held:
            if m not in done:
                done.add(m)
                out.append((int(f["index"]), m, m in (u.get("confirmed_others") or [])))
    return out


def score(traces: list[dict[str, Any]], crosstalk: CrossTalk, k: int) -> dict[str, Any]:
    confirmed_faults = spurious = total = agree = 0
    faults = 0
    delays = []
    for t in traces:
        carried = {int(f["index"]): {(x["position"], x["mode"]) for x in f["faults"]}
                   for f in t["truth"]["flights"]}
        got = {pos: _unit_confirmations(t, pos, crosstalk, k) for pos in POSITIONS}
        for pos, rows in got.items():
            total += len(rows)
            spurious += sum((pos, m) not in carried.get(i, set()) for i, m, _ in rows)
            agree += sum(same for *_, same in rows)
        for fact in score_pattern(t)["faults"]:
            faults += 1
            pos, mode = fact["position"], fact["mode"]
            by_class = next((int(f["index"]) for f in t["flights"]
                             if int(f["index"]) <= fact["end"]
                             and (f["units"].get(pos) or {}).get("confirmed") == mode), None)
            beside = next((i for i, m, _ in got[pos] if m == mode and i <= fact["end"]), None)
            when = min((x for x in (by_class, beside) if x is not None), default=None)
            if when is not None:
                confirmed_faults += 1
                if fact["named"] is not None:
                    delays.append(when - fact["named"])
    return {"feature_flights": k, "faults": faults, "confirmed": confirmed_faults,
            "confirmed_interval": proportion_interval(confirmed_faults, faults),
            "confirmations_beside": total, "spurious": spurious,
            "spurious_interval": proportion_interval(spurious, total) if total else None,
            "agree_with_traces": agree,
            "named_to_confirmed_mean": float(np.mean(delays)) if delays else None,
            "named_to_confirmed_p90": float(np.percentile(delays, 90)) if delays else None}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("evaluations", nargs="+", type=Path,
                    help="hmsm evaluate --out dirs of concurrent campaigns")
    ap.add_argument("--model", type=Path, required=True, help="the model they were run with")
    ap.add_argument("--out", type=Path)
    args = ap.parse_args()
    model = read_model_document(json.loads(args.model.read_text(encoding="utf-8")))
    if model.crosstalk is None:
        raise SystemExit(f"{args.model} has no cross-talk limits: nothing is named by feature")
    traces = _traces(args.evaluations)
    rows = [score(traces, model.crosstalk, k) for k in RUN_LENGTHS]
    print("| feature flights | faults confirmed | confirmations beside the leader | spurious "
          "| as the traces | named -> confirmed: mean, p90 |")
    print("|---|---|---|---|---|---|")
    for r in rows:
        mean = "-" if r["named_to_confirmed_mean"] is None else (
            f"{r['named_to_confirmed_mean']:.1f}, {r['named_to_confirmed_p90']:.0f}")
        print(f"| {r['feature_flights']} | {r['confirmed']} / {r['faults']} | "
              f"{r['confirmations_beside']} | {r['spurious']} | {r['agree_with_traces']} | "
              f"{mean} |")
    print(f"{len(traces)} patterns; the service's feature flights: "
          f"{CONFIRMATION.feature_flights}")
    if args.out:
        args.out.write_text(json.dumps({"rows": rows, "model": str(args.model),
                                        "evaluations": [str(d) for d in args.evaluations]},
                                       indent=1) + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()
