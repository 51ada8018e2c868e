"""The RUL bands per fault mode and speed group, from ``hmsm evaluate`` outputs.

    python bench/rul_speed_groups.py --out docs/results/rul_speed_groups.json \\
        "in range=/tmp/eval_range" "fast=/tmp/eval_fast" "very fast=/tmp/eval_vfast" \\
        "slow=/tmp/eval_slow"

Per group and mode: the patterns and predictions scored, the share of predictions whose 50 %
and 90 % bands hold the true RUL (mean [90 % bootstrap interval over patterns], from the
evaluation's summary), the share whose truth lies below the 90 % band, the mean band widths
[flights] and the median 90 % width over the true RUL, the median relative error of the
median RUL ((median - true) / true over every scored prediction), Saxena's PH (over the life)
and the mean relative accuracy RA [%]. Prints a markdown table; writes the figures as JSON.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np


def _median_relative_error(patterns: list[dict[str, Any]]) -> float | None:
    errs = [(p["point"] - p["true_rul"]) / p["true_rul"]
            for pat in patterns for p in pat.get("predictions", [])
            if p["point"] is not None and p["true_rul"] > 0]
    return float(np.median(errs)) if errs else None


def _below_and_width(patterns: list[dict[str, Any]]) -> tuple[float | None, float | None]:
    """Share of predictions whose truth lies below the 90 % band's lower end (the band
    promised life that was not there), and the median of the 90 % width over the true RUL
    (an open upper end counts as infinite)."""
    preds = [p for pat in patterns for p in pat.get("predictions", [])
             if p.get("q05") is not None and p["true_rul"] > 0]
    if not preds:
        return None, None
    below = float(np.mean([p["true_rul"] < p["q05"] for p in preds]))
    ratio = [np.inf if p.get("q95") is None else (p["q95"] - p["q05"]) / p["true_rul"]
             for p in preds]
    return below, float(np.median(ratio))


def group_figures(eval_dir: Path) -> dict[str, Any]:
    summary = json.loads((eval_dir / "summary.json").read_text())
    full = json.loads((eval_dir / "evaluation.json").read_text())
    out: dict[str, Any] = {}
    for mode, r in summary["prognosis"].items():
        cal = r["calibration"]
        patterns = full["prognosis"][mode].get("patterns", [])
        below, width_ratio = _below_and_width(patterns)
        out[mode] = {
            "patterns": r["n_patterns"], "predictions": cal["n_predictions"],
            "cover_50": cal["central_50"], "cover_50_ci": cal["central_50_ci"],
            "cover_90": cal["central_90"], "cover_90_ci": cal["central_90_ci"],
            "width_50": cal["width_50_flights"], "width_90": cal["width_90_flights"],
            "median_rel_error": _median_relative_error(patterns),
            "below_90": below, "width_90_over_rul": width_ratio,
            "ph": r["ph"], "ph_ci": r["ph_ci"], "ra": r["ra"], "ra_ci": r["ra_ci"]}
    return out


def _fmt(v: float | None, ci: list[float] | None = None, digits: int = 2) -> str:
    if v is None:
        return "-"
    text = f"{v:.{digits}f}"
    if ci and all(c is not None for c in ci):
        text += f" [{ci[0]:.{digits}f}, {ci[1]:.{digits}f}]"
    return text


def markdown(groups: dict[str, dict[str, Any]]) -> str:
    rows = ["| group | mode | patterns / predictions | 50 % held | 90 % held | truth below "
            "90 % | width 50 / 90 [flights] | 90 % width / RUL (median) | median rel. error "
            "| PH | RA [%] |", "|---" * 11 + "|"]
    for name, modes in groups.items():
        for mode, f in modes.items():
            rows.append(
                f"| {name} | {mode} | {f['patterns']} / {f['predictions']} "
                f"| {_fmt(f['cover_50'], f['cover_50_ci'])} "
                f"| {_fmt(f['cover_90'], f['cover_90_ci'])} | {_fmt(f.get('below_90'))} "
                f"| {_fmt(f['width_50'], digits=0)} / {_fmt(f['width_90'], digits=0)} "
                f"| {_fmt(f.get('width_90_over_rul'))} | {_fmt(f['median_rel_error'])} "
                f"| {_fmt(f['ph'], f['ph_ci'])} "
                f"| {_fmt(f['ra'], f['ra_ci'], 1)} |")
    return "\n".join(rows)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("groups", nargs="+", metavar="NAME=EVAL_DIR")
    parser.add_argument("--out", default=None, help="JSON file to write")
    args = parser.parse_args(argv)
    groups = {}
    for spec in args.groups:
        name, _, path = spec.partition("=")
        if not path:
            parser.error(f"{spec!r}: expected NAME=EVAL_DIR")
        groups[name] = group_figures(Path(path))
    print(markdown(groups))
    if args.out:
        Path(args.out).write_text(json.dumps(groups, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
