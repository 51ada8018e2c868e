"""Choose the rule that confirms an alarm's class, on design seeds' evaluations.

The rule (:mod:`server.phm.classification.confirmation`) reads only the class probabilities
the chain showed on each flight from the alarm on, which every evaluation keeps in its traces;
so each setting is scored from ``evaluation.json`` files in seconds, without running the chain
again. For every setting of the grid: classification at confirmation (share right over the
detected faults, exact 90 % interval), faults never confirmed, and the flights from the first
alarm to confirmation (mean, 90th percentile). The choice: the fewest mean flights among the
settings whose share right is at or above ``--target`` (98 % at confirmation) and that confirm
every detected fault. Its interval is reported, not required above the target: a lower 90 %
bound of 98 % needs about 150 patterns, all right.

    python bench/confirmation_rule.py EVAL_DIR [EVAL_DIR ...] [--target 0.98] [--out F.json]

Score the chosen setting on verification evaluations once, with ``hmsm evaluate`` (the
service's rule is ``CONFIRMATION``).
"""

from __future__ import annotations

import argparse
import json
from itertools import product
from pathlib import Path
from typing import Any

from server.evaluation.scoring import (
    UNCONFIRMED,
    confirmation_delays,
    confirmation_of,
    detection_of,
)
from server.phm.classification.confirmation import ConfirmationRule
from server.phm.metrics import proportion_interval

FLIGHTS = (1, 2, 3, 4)
PROBABILITIES = (0.5, 0.6, 0.7, 0.8, 0.9, 0.95, 0.98)


def _traces(dirs: list[Path]) -> list[dict[str, Any]]:
    traces = []
    for d in dirs:
        doc = json.loads((d / "evaluation.json").read_text(encoding="utf-8"))
        traces += [t for t in doc["patterns"] if t["mode"] != "healthy"]
    return traces


def score(rule: ConfirmationRule, traces: list[dict[str, Any]]) -> dict[str, Any]:
    """The rule's figures over the detected faults of ``traces``."""
    found = [(t, d) for t in traces if (d := detection_of(t)["detected_index"]) is not None]
    got = [(t["mode"], *confirmation_of(t, d, rule)) for t, d in found]
    confirmed = [(m, c) for m, c, _ in got if c != UNCONFIRMED]
    right = sum(m == c for m, c in confirmed)
    return {"flights": rule.flights, "probability": rule.probability,
            "detected": len(found), "right": right, "share": right / len(confirmed)
            if confirmed else None,
            "interval": proportion_interval(right, len(confirmed)) if confirmed else None,
            **confirmation_delays([k for _, c, k in got if c != UNCONFIRMED] +
                                  [None for _, c, _ in got if c == UNCONFIRMED])}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("evaluations", nargs="+", type=Path, help="hmsm evaluate --out dirs")
    ap.add_argument("--target", type=float, default=0.98)
    ap.add_argument("--out", type=Path)
    args = ap.parse_args()
    traces = _traces(args.evaluations)
    rows = [score(ConfirmationRule(f, p), traces) for f, p in product(FLIGHTS, PROBABILITIES)]
    print("| flights | probability | right / confirmed | share [90 %] | never | mean | p90 |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        share = "-" if r["share"] is None else (
            f"{r['share']:.3f} [{r['interval'][0]:.3f}, {r['interval'][1]:.3f}]")
        mean = "-" if r["mean"] is None else f"{r['mean']:.1f}"
        p90 = "-" if r["p90"] is None else f"{r['p90']:.0f}"
        print(f"| {r['flights']} | {r['probability']} | {r['right']} / {r['confirmed']} | "
              f"{share} | {r['unconfirmed']} | {mean} | {p90} |")
    ok = [r for r in rows if r["unconfirmed"] == 0 and r["share"] is not None
          and r["share"] >= args.target]
    chosen = min(ok, key=lambda r: (r["mean"], r["flights"], r["probability"])) if ok else None
    print(f"chosen: {chosen and (chosen['flights'], chosen['probability'])} "
          f"on {len(traces)} fault patterns")
    if args.out:
        args.out.write_text(json.dumps({"rows": rows, "chosen": chosen,
                                        "evaluations": [str(d) for d in args.evaluations]},
                                       indent=1) + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()
