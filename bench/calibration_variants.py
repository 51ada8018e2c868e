"""Choose between calibration layers from stored replays, in seconds: each variant's layer fitted
on uncalibrated replays of the calibration designs, applied to uncalibrated replays of choice
designs kept apart, and scored against the suite's targets.

    python bench/calibration_variants.py \\
        --replays "every third=C3/cal-fast,C3/cal-medium,C3/cal-slow" \\
        --replays "fast every flight=C1/cal-fast,C3/cal-medium,C3/cal-slow" \\
        --split 0 --split 0.8 \\
        --choice "choice fast=CH/choice-fast" --choice "choice medium=CH/choice-medium"

(C3, C1, CH: the uncalibrated model's evaluations under ``ROOT/scores/<model stem>/``, as
``bench/rul_suite.py score`` keeps them.) The
layer is applied as the chain applies it (:meth:`BandCalibration.apply` on each replayed
prediction), so a variant's figures are those its calibrated model would give on the same
replays: the 10 scored predictions per run that ``hmsm evaluate`` picks, their 50 % and 90 %
bands held, the truth below the 90 % band, the median 90 % width over the true RUL and the
mean relative accuracy of the median. A variant meets a target per mode and set: 90 % held
0.85-0.95, truth below at most 0.075, 50 % held 0.40-0.60, width at most 1.5 x RUL.
"""

from __future__ import annotations

import argparse
import itertools
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

from server.evaluation.band_calibration import calibration_records
from server.phm.prognosis.calibration import BandCalibration, fit_band_calibration
from server.phm.prognosis.hypotheses import band_names
from server.phm.prognosis.predictor import RulDistribution
from server.phm.training import TrainingConfig

#: the bank's hypotheses, as training names them
HYPOTHESES = tuple(name for name, _, _ in band_names(TrainingConfig().rate_band_edges))


def _evaluation(path: str) -> dict[str, Any]:
    p = Path(path)
    return json.loads((p / "evaluation.json" if p.is_dir() else p).read_text())


def layers(replays: list[dict[str, Any]], split: float | None) -> dict[str, BandCalibration]:
    """Each mode's layer fitted on ``replays`` (grouped by the bank's leads, split at
    ``split``)."""
    records, _ = calibration_records([t for e in replays for t in e["patterns"]], per_run=20)
    return {mode: fit_band_calibration(recs, hypotheses=HYPOTHESES, weight_split=split)
            for mode, recs in records.items()}


def scored(evaluation: dict[str, Any], layer: dict[str, BandCalibration]
           ) -> dict[str, dict[str, float]]:
    """Per mode, the figures of the evaluation's scored predictions with ``layer`` applied."""
    docs = {(t["id"], f["index"]): f["rul"] for t in evaluation["patterns"]
            for f in t["flights"] if f.get("rul")}
    out = {}
    for mode, rows in evaluation["prognosis"].items():
        q = []
        for pattern in rows["patterns"]:
            for p in pattern["predictions"]:
                doc = docs.get((pattern["id"], p["flight"]))
                if doc is None or p["true_rul"] <= 0:
                    continue
                dist = RulDistribution.from_json(json.dumps(doc))
                dist = layer[mode].apply(dist) if mode in layer else dist
                q.append([dist.quantiles[lv] for lv in (0.05, 0.25, 0.5, 0.75, 0.95)]
                         + [p["true_rul"]])
        lo, q25, med, q75, hi, y = np.array(q, dtype=float).T
        out[mode] = {"predictions": len(y), "cover_50": float(np.mean((y >= q25) & (y <= q75))),
                     "cover_90": float(np.mean((y >= lo) & (y <= hi))),
                     "below_90": float(np.mean(y < lo)),
                     "width_90_over_rul": float(np.median((hi - lo) / y)),
                     "ra": float(100 * np.mean(1 - np.abs(y - med) / y))}
    return out


def targets_met(f: dict[str, float]) -> int:
    return sum((0.85 <= f["cover_90"] <= 0.95, f["below_90"] <= 0.075,
                0.40 <= f["cover_50"] <= 0.60, f["width_90_over_rul"] <= 1.5))


def _named(pairs: list[str]) -> dict[str, list[str]]:
    out = {}
    for pair in pairs:
        name, sep, paths = pair.partition("=")
        if not sep or not paths:
            raise SystemExit(f"expected NAME=PATH[,PATH...], got {pair!r}")
        out[name] = paths.split(",")
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--replays", action="append", required=True,
                    help="NAME=EVAL[,EVAL...]: a variant's calibration replays")
    ap.add_argument("--split", action="append", type=float, default=None,
                    help="leader's weight split to try (0: none); repeatable")
    ap.add_argument("--choice", action="append", required=True, help="NAME=EVAL: a choice set")
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args(argv)
    choice = {name: _evaluation(paths[0]) for name, paths in _named(args.choice).items()}
    results: dict[str, Any] = {}
    print("| variant | set | mode | 50 % held | 90 % held | truth below | width / RUL | RA [%] |")
    print("|---|---|---|---|---|---|---|---|")
    for (name, paths), split in itertools.product(_named(args.replays).items(),
                                                  args.split or [0.0]):
        label = f"{name}, split {split:g}" if split else name
        layer = layers([_evaluation(p) for p in paths], split or None)
        figures = {c: scored(ev, layer) for c, ev in choice.items()}
        met = sum(targets_met(f) for per_mode in figures.values() for f in per_mode.values())
        results[label] = {"targets_met": met, "sets": figures}
        for c, per_mode in figures.items():
            for mode, f in sorted(per_mode.items()):
                print(f"| {label} | {c} | {mode} | {f['cover_50']:.2f} | {f['cover_90']:.2f} | "
                      f"{f['below_90']:.3f} | {f['width_90_over_rul']:.2f} | {f['ra']:.1f} |")
        print(f"| {label} | targets met | {met} of "
              f"{4 * sum(len(v) for v in figures.values())} | | | | | |", flush=True)
    if args.out:
        args.out.write_text(json.dumps(results, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
