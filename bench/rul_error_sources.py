"""Where a mode's RUL error comes from: the raw predictions of an ``hmsm evaluate`` run split by
the share of life gone, the fault's span, the bank's leading hypothesis and the position.

    python bench/rul_error_sources.py EVAL_DIR MTWEAR

Per split: the predictions, the median relative error of the median RUL ((median - true) /
true), its median in flights, the filter's severity lag (true severity - the filter's mean)
and that lag times the span [flights] (what a lagging level alone would add to the RUL of a
fault growing at one threshold per span), the share of truths below the 90 % band and its
median width over the true RUL. A RUL error much larger than the lag in flights comes from
the rate, not from the level (the wingtip's screw wear on the fast calibration design: +101 %
with a lag of 4 flights, its rate clipped by the filter's rate bounds).
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np


def predictions(eval_dir: Path, mode: str) -> list[dict[str, Any]]:
    """Every prediction of ``mode``'s fault patterns with its truth and where it was made."""
    ev = json.loads((eval_dir / "evaluation.json").read_text())
    rows = []
    for t in ev["patterns"]:
        if t["mode"] != mode or t["failure"] is None or t["onset"] is None:
            continue
        span = t["failure"] - t["onset"]
        for f in t["flights"]:
            r = f["rul"]
            if r is None or f["true_rul"] is None or f["true_rul"] <= 0:
                continue
            q = {float(level): v for level, v in r["quantiles"]}
            if q.get(0.5) is None:
                continue
            rows.append({"span": span, "life": (f["index"] - t["onset"]) / span,
                         "true": f["true_rul"], "median": q[0.5], "q05": q.get(0.05),
                         "q95": q.get(0.95), "lag": f["severity_norm"] - r["severity_mean"],
                         "lead": (r.get("hypothesis") or {}).get("name"),
                         "position": t["position"]})
    return rows


def figures(rows: list[dict[str, Any]]) -> dict[str, float]:
    """The split's figures (see the module's docstring)."""
    true = np.array([r["true"] for r in rows], dtype=float)
    med = np.array([r["median"] for r in rows], dtype=float)
    lag = np.array([r["lag"] for r in rows], dtype=float)
    span = np.array([r["span"] for r in rows], dtype=float)
    width = [np.inf if r["q95"] is None or r["q05"] is None else (r["q95"] - r["q05"]) / r["true"]
             for r in rows]
    return {"n": len(rows), "relative_error": float(np.median((med - true) / true)),
            "error_flights": float(np.median(med - true)), "lag": float(np.median(lag)),
            "lag_flights": float(np.median(lag * span)),
            "below_90": float(np.mean([r["q05"] is not None and r["true"] < r["q05"]
                                       for r in rows])),
            "width_90_over_rul": float(np.median(width))}


def splits(rows: list[dict[str, Any]]) -> dict[str, list[dict[str, Any]]]:
    """The predictions by share of life gone, span, leading hypothesis and position."""
    out: dict[str, list[dict[str, Any]]] = {}

    def add(label: str, keep: Callable[[dict[str, Any]], bool]) -> None:
        chosen = [r for r in rows if keep(r)]
        if chosen:
            out[label] = chosen

    for lo, hi in ((0.0, 0.25), (0.25, 0.5), (0.5, 0.75), (0.75, 1.01)):
        add(f"life {lo:.2f}-{min(hi, 1.0):.2f}", lambda r, lo=lo, hi=hi: lo <= r["life"] < hi)
    for lo, hi in ((0, 50), (50, 70), (70, 100), (100, 300), (300, 1000), (1000, 10**6)):
        add(f"span {lo}-{hi}", lambda r, lo=lo, hi=hi: lo <= r["span"] < hi)
    for lead in sorted({str(r["lead"]) for r in rows}):
        add(f"lead {lead}", lambda r, lead=lead: str(r["lead"]) == lead)
    for pos in sorted({r["position"] for r in rows}):
        add(f"position {pos}", lambda r, pos=pos: r["position"] == pos)
    add("all", lambda r: True)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("evaluation", type=Path, help="an `hmsm evaluate --out` directory")
    ap.add_argument("mode", help="a progressive fault mode, e.g. MTWEAR")
    ap.add_argument("--json", type=Path, default=None, help="write the figures here")
    args = ap.parse_args(argv)
    rows = predictions(args.evaluation, args.mode)
    if not rows:
        ap.error(f"no {args.mode} predictions in {args.evaluation}")
    table = {label: figures(chosen) for label, chosen in splits(rows).items()}
    print("| split | n | median rel. error | error [flights] | severity lag | lag x span "
          "[flights] | truth below 90 % | 90 % width / RUL |")
    print("|---|---|---|---|---|---|---|---|")
    for label, f in table.items():
        print(f"| {label} | {f['n']} | {f['relative_error']:+.2f} | {f['error_flights']:+.1f} | "
              f"{f['lag']:+.3f} | {f['lag_flights']:+.1f} | {f['below_90']:.2f} | "
              f"{f['width_90_over_rul']:.2f} |")
    if args.json:
        args.json.write_text(json.dumps({"evaluation": str(args.evaluation), "mode": args.mode,
                                         "splits": table}, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
