"""How the chain's RUL bands hold on faults faster or slower than any in design, per variant of
the training constants (``server.phm.training.TrainingConfig``).

Run (from the repository root)::

    python bench/adaptation.py --design DIR --score DIR [DIR ...] \
        [--variant NAME:FIELD=VALUE[,FIELD=VALUE ...] ...] [--jobs 2] [--out PATH]

Trains the chain on ``--design`` once per variant (``base:`` is ``TrainingConfig()`` as every
model is trained) and scores every ``--score`` campaign with it. Per campaign and progressive
mode it prints the share of predictions whose central 50 % / 90 % RUL interval holds the true
RUL, the mean 90 % width in flights, PH (Saxena) and RA, each over the campaign's patterns, and
writes them as JSON (``--out``, default ``adaptation.json`` in the working directory).

Choose on design campaigns flown with spans outside the training design's (for example
``sim-worker campaign --kind design --seed 3 --scale quick --span-range 50,150
--render-every 1``); verification campaigns are scored once, with the chosen variant.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from server.campaigns import load_campaign  # noqa: E402
from server.evaluation.runner import evaluate_campaign  # noqa: E402
from server.phm.training import TrainingConfig, train_phm_model  # noqa: E402


def parse_variant(text: str) -> tuple[str, TrainingConfig]:
    """``NAME:FIELD=VALUE,...`` -> (NAME, TrainingConfig with those fields); the values are
    numbers, tuples of numbers written ``a/b`` (nothing: the empty tuple), or the word a text
    field takes."""
    name, _, body = text.partition(":")
    if not name:
        raise ValueError(f"variant {text!r}: NAME:FIELD=VALUE,... expected")
    fields = {f.name: f for f in dataclasses.fields(TrainingConfig)}
    changes: dict[str, Any] = {}
    for item in filter(None, body.split(",")):
        key, sep, value = item.partition("=")
        if not sep or key not in fields:
            raise ValueError(f"variant {name!r}: unknown field {key!r} (known: "
                             f"{', '.join(sorted(fields))})")
        if isinstance(getattr(TrainingConfig, key, None), str):
            changes[key] = value
            continue
        if not value:  # an empty tuple, e.g. rate_band_edges= (no bank)
            changes[key] = ()
            continue
        parts = [float(v) for v in value.split("/")]
        changes[key] = tuple(parts) if len(parts) > 1 else parts[0]
    return name, TrainingConfig(**changes)


def mode_rows(summary: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """Per progressive mode: coverage 50 / 90 %, 90 % width, PH, RA, predictions."""
    rows = {}
    for mode, r in summary["prognosis"].items():
        cal = r.get("calibration") or {}
        rows[mode] = {"central_50": cal.get("central_50"), "central_90": cal.get("central_90"),
                      "width_90_flights": cal.get("width_90_flights"),
                      "predictions": cal.get("n_predictions"), "ph": r.get("ph"),
                      "ra": r.get("ra"), "patterns": r.get("n_patterns")}
    return rows


def _f(v: Any, spec: str) -> str:
    return "-" if v is None else format(v, spec)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--design", required=True, help="design campaign to train on")
    ap.add_argument("--score", nargs="+", required=True, help="campaigns to score")
    ap.add_argument("--variant", action="append", default=None,
                    help="NAME:FIELD=VALUE,... of TrainingConfig (repeatable; default base:)")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--seed", type=int, default=0, help="training seed")
    ap.add_argument("--out", default="adaptation.json")
    args = ap.parse_args(argv)
    variants = [parse_variant(v) for v in (args.variant or ["base:"])]
    design = load_campaign(args.design, jobs=args.jobs)
    scored = {d: load_campaign(d, jobs=args.jobs) for d in args.score}
    out: dict[str, Any] = {"design": str(Path(args.design).resolve()), "variants": {}}
    for name, training in variants:
        t0 = time.perf_counter()
        model, _ = train_phm_model(design, seed=args.seed, training=training)
        result: dict[str, Any] = {"training": dataclasses.asdict(training), "campaigns": {}}
        for d, camp in scored.items():
            summary = evaluate_campaign(model, d, jobs=args.jobs, timing_flights=0,
                                        campaign=camp)
            rows = mode_rows(summary)
            result["campaigns"][str(Path(d).resolve())] = rows
            print(f"\n{name} on {d} ({time.perf_counter() - t0:.0f} s)")
            print("mode    cov50  cov90  width90  PH    RA     predictions")
            for mode, r in rows.items():
                print(f"{mode:7} {_f(r['central_50'], '.2f'):6} {_f(r['central_90'], '.2f'):6} "
                      f"{_f(r['width_90_flights'], '.0f'):8} {_f(r['ph'], '.2f'):5} "
                      f"{_f(r['ra'], '.1f'):6} {_f(r['predictions'], 'd')}")
        out["variants"][name] = result
    Path(args.out).write_text(json.dumps(out, indent=1, default=str))
    print(f"\nwrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
