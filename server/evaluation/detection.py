"""Detection alone: fit baselines and detector on a design campaign, score a verification one.

Usage::

    python -m server.evaluation.detection --design DIR --verification DIR [--jobs 2]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from collections.abc import Sequence
from pathlib import Path

from server.campaigns import load_campaign
from server.evaluation.evaluate_detection import evaluate, format_report, summarise
from server.phm.baselines import BASELINE_DEFAULTS, FleetBaseline
from server.phm.detection_model import fit_detection

__all__ = ["main"]


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--design", required=True, help="design campaign directory")
    ap.add_argument("--verification", required=True, help="verification campaign directory")
    ap.add_argument("--jobs", type=int, default=min(2, os.cpu_count() or 1))
    ap.add_argument("--model-out", help="write the fitted detection model (JSON) here")
    ap.add_argument("--no-cache", action="store_true", help="do not cache features")
    ap.add_argument("--pooled-slopes", action="store_true",
                    help="compare: the baselines' slopes from all flights pooled, not within "
                    "units")
    ap.add_argument("--raw-ratios", action="store_true",
                    help="compare: F_SE and F_BDO on their value, not its log")
    args = ap.parse_args(argv)
    design = load_campaign(args.design, jobs=args.jobs, cache=not args.no_cache)
    model = fit_detection(design, baseline=FleetBaseline(
        within_units=not args.pooled_slopes,
        log_features=() if args.raw_ratios else BASELINE_DEFAULTS.log_features))
    if args.model_out:
        Path(args.model_out).write_text(json.dumps(model.to_dict(), indent=1))
    verification = load_campaign(args.verification, jobs=args.jobs, cache=not args.no_cache)
    outcomes = evaluate(model, verification)
    n_air = len({p.aircraft for p in verification.patterns})
    print(f"design: {args.design} ({len(design.patterns)} patterns); verification: "
          f"{args.verification} ({len(verification.patterns)} patterns, {n_air} aircraft)")
    print(f"alarm at separation confidence {model.detector.alarm_confidence} "
          f"(= {model.detector.z_alarm:.2f} standard errors beyond the healthy band), windows "
          f"{list(model.detector.windows)} flights")
    print(format_report(summarise(outcomes)))
    for o in outcomes:
        if o.mode != "healthy" and o.detected_index is None:
            print(f"missed: {o.id} {o.mode} {o.aircraft}/{o.position}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
