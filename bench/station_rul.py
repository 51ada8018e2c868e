"""The RUL bands on test-station injections: each injection flown as ``sim-worker run`` flies it
(steered to the operator's time to failure, :mod:`sim_worker.span_check`), every flight's
features computed as the service computes them and the chain run over them with a model.

    python bench/station_rul.py --model MODEL.json --per-mode 4 --span-range 40,200 \\
        --out station_rul.json                               # about 10 min on 2 cores
    python bench/station_rul.py --model MODEL.json --modes MTEL,DMD --per-mode 2 \\
        --span-range 60,60 --out station_60.json             # the demo's 60-flight case

An injection's actuator flies ``--lead`` healthy flights first (a unit installed shortly
before: the detector learns its offsets from them), then the fault from its start to failure.
Scored from the first alarm to the failure, every flight: the share of predictions whose
50 % and 90 % bands hold the true RUL, the median relative error of the median RUL, the
mean 90 % width, per mode.
"""

from __future__ import annotations

import argparse
import json
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from server.phm.chain import analyze_flight, read_model_document  # noqa: E402
from server.phm.recording import log_features  # noqa: E402
from server.vocabulary import POSITIONS, PROGRESSIVE  # noqa: E402
from sim_worker.faults import healthy  # noqa: E402
from sim_worker.flight import flight_start, reference_summary, simulate_flight  # noqa: E402
from sim_worker.service import fleet_plan  # noqa: E402
from sim_worker.span_check import _N_AIRCRAFT, SpanCase, hash_case, span_cases  # noqa: E402
from sim_worker.steering import plan_fault, steer_and_advance  # noqa: E402


def fly_and_analyse(case: SpanCase, model_doc: dict[str, Any], seed: int, duration_s: float,
                    lead: int, flat_season: bool = False) -> dict[str, Any]:
    """One injection flown to failure with the chain over every flight; its predictions
    (``flat_season``: steered as if every flight to come were the reference flight, not
    following the base's season)."""
    model = read_model_document(model_doc)
    aircraft = fleet_plan(_N_AIRCRAFT, seed)[case.aircraft]
    rng = np.random.default_rng([seed, 41, hash_case(case)])
    reference = reference_summary(aircraft, case.position, duration_s=duration_s,
                                  seed=(seed, 12, case.aircraft))
    plan = None
    fault = healthy()
    health = {p: model.new_health(p) for p in POSITIONS}
    rows = []
    n = max(case.start_flight - lead, 0)  # a unit installed at flight 0 flies fewer
    while n < case.start_flight + 3 * case.span:
        if n == case.start_flight:
            fault, plan = plan_fault(case.mode, case.position, rng, reference=reference,
                                     start_flight=case.start_flight,
                                     span_flights=float(case.span),
                                     base=None if flat_season else aircraft.base)
        flight_rng = np.random.default_rng([seed, 13, hash_case(case), n])
        log, summary = simulate_flight(aircraft, fault, n, flight_rng,
                                       started_at=flight_start(n), duration_s=duration_s)
        out = analyze_flight(model, log_features(log, ground_temp_c=summary.ground_temp_c),
                             health, seed=hash_case(case), flight_index=n,
                             started_at=flight_start(n), base=aircraft.base)[case.position]
        rows.append({"flight": n, "alarm": bool(out.alarm), "mode": out.fault_mode,
                     "quantiles": None if out.rul is None else
                     {str(k): v for k, v in out.rul.quantiles.items()},
                     "severity": fault.severity_norm if fault.mode != "healthy" else 0.0,
                     "estimate": None if out.rul is None else out.rul.severity_mean,
                     "rate_ratio": None if out.rul is None else out.rul.rate_ratio,
                     "adjustment": None if out.rul is None else out.rul.adjustment})
        if fault.failed:
            break
        if plan is not None:
            plan = steer_and_advance(plan, summary, n,
                                     np.random.default_rng([seed, 14, hash_case(case), n]))
            fault = plan.state
        n += 1
    failure = n if fault.failed else None
    return {"mode": case.mode, "position": case.position, "aircraft": aircraft.tail,
            "start": case.start_flight, "requested": case.span, "failure": failure,
            "predictions": _predictions(rows, case.start_flight, failure)}


def _predictions(rows: list[dict[str, Any]], start: int, failure: int | None
                 ) -> list[dict[str, Any]]:
    if failure is None:
        return []
    alarm = next((r["flight"] for r in rows if r["flight"] >= start and r["alarm"]), None)
    if alarm is None:
        return []
    return [{"flight": r["flight"], "true_rul": failure - r["flight"], "mode_used": r["mode"],
             "severity": r["severity"], "estimate": r["estimate"],
             "rate_ratio": r["rate_ratio"], "adjustment": r["adjustment"],
             **{f"q{k}": r["quantiles"][str(v)] for k, v in
                (("05", 0.05), ("25", 0.25), ("50", 0.5), ("75", 0.75), ("95", 0.95))}}
            for r in rows if alarm <= r["flight"] < failure and r["quantiles"]]


def summarise(records: list[dict[str, Any]]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for mode in PROGRESSIVE:
        runs = [r for r in records if r["mode"] == mode]
        preds = [p for r in runs for p in r["predictions"]]
        if not runs:
            continue
        t = np.array([p["true_rul"] for p in preds], dtype=float)
        q = {k: np.array([p[k] for p in preds], dtype=float)
             for k in ("q05", "q25", "q50", "q75", "q95")}
        per_run_90 = [float(np.mean([p["q05"] <= p["true_rul"] <= p["q95"]
                                     for p in r["predictions"]]))
                      for r in runs if r["predictions"]]
        out[mode] = {
            "injections": len(runs), "failed": sum(r["failure"] is not None for r in runs),
            "with_predictions": len(per_run_90), "predictions": int(t.size),
            "held_50": float(np.mean((q["q25"] <= t) & (t <= q["q75"]))) if t.size else None,
            "held_90": float(np.mean((q["q05"] <= t) & (t <= q["q95"]))) if t.size else None,
            "held_90_per_injection": per_run_90,
            "median_rel_error": float(np.median((q["q50"] - t) / np.maximum(t, 1)))
            if t.size else None,
            "width_90": float(np.mean(q["q95"] - q["q05"])) if t.size else None}
    return out


def _job(args: tuple[SpanCase, dict[str, Any], int, float, int, bool]) -> dict[str, Any]:
    return fly_and_analyse(*args)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--model", required=True, help="model document (hmsm train --out)")
    parser.add_argument("--per-mode", type=int, default=4)
    parser.add_argument("--span-range", default="40,200", metavar="LOW,HIGH")
    parser.add_argument("--modes", default=",".join(PROGRESSIVE))
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--duration", type=float, default=60.0, help="recording length [s]")
    parser.add_argument("--lead", type=int, default=20, help="healthy flights first")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--flat-season", action="store_true",
                        help="steer as if the flights to come had the reference flight's "
                        "driver (the station's rule before it followed the season)")
    parser.add_argument("--out", required=True)
    args = parser.parse_args()
    lo, hi = (int(v) for v in args.span_range.split(","))
    modes = tuple(m for m in args.modes.split(",") if m)
    cases = span_cases(args.per_mode, args.seed, (lo, hi), modes=modes)
    doc = json.loads(Path(args.model).read_text())
    jobs = [(c, doc, args.seed, args.duration, args.lead, args.flat_season) for c in cases]
    with ProcessPoolExecutor(args.workers) as pool:
        records = list(pool.map(_job, jobs))
    summary = summarise(records)
    Path(args.out).write_text(json.dumps({"settings": vars(args), "summary": summary,
                                          "injections": records}, indent=1) + "\n")
    for mode, s in summary.items():
        print(f"{mode}: {s['injections']} injections ({s['with_predictions']} predicted), "
              f"{s['predictions']} predictions, 50 % held {s['held_50']}, 90 % held "
              f"{s['held_90']}, median rel. error {s['median_rel_error']}, "
              f"90 % width {s['width_90']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
