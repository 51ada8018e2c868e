"""``hmsm calibrate``: fit the RUL bands' calibration layer on replays of calibration design runs.

Usage::

    hmsm evaluate --campaign CAL_DESIGN --model-json model.json --out CAL_EVAL
    hmsm calibrate --evaluation CAL_EVAL --model-json model.json --out model_calibrated.json

The evaluation replays the chain over a design campaign kept for calibration only (never the
one the model was trained on: ``--model-json``'s training campaign is refused). Each
progressive run gives up to ``--per-run`` predictions evenly spaced from its first alarm to
its failure (every run counts alike, however long its life); each prediction's band, the
filter's rate ratio and the true RUL are the layer's records, grouped by the mode whose filter
made the prediction (:mod:`server.phm.prognosis.calibration`). The model document is written
again with each mode's layer in its measurement spec.
"""

from __future__ import annotations

import argparse
import json
import math
from collections import defaultdict
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from server.phm.chain.model import _unwrap, read_model_document
from server.phm.prognosis.calibration import (
    BAND_LEVELS,
    DEFAULT_WEIGHT_SPLIT,
    CalibrationRecord,
    fit_band_calibration,
)
from server.vocabulary import PROGRESSIVE

__all__ = ["add_calibrate_arguments", "calibration_records", "calibrate_model",
           "run_calibrate"]

_LEVELS = sorted({lv for pair in BAND_LEVELS.values() for lv in pair} | {0.5})


def _first_alarm(trace: Mapping[str, Any]) -> int | None:
    onset = int(trace["onset"] or 0)
    for f in trace["flights"]:
        if f["index"] >= onset and f["alarm"]:
            return int(f["index"])
    return None


def _record(flight: Mapping[str, Any]) -> CalibrationRecord | None:
    doc = flight.get("rul")
    if not doc or flight.get("true_rul") is None:
        return None
    if doc.get("adjustment") and "conformal_margins" in doc["adjustment"]:
        raise ValueError("these replays were made with a calibrated model: calibrate on the "
                         "uncalibrated model's replays")
    quantiles = {float(q): (math.inf if v is None else float(v)) for q, v in doc["quantiles"]}
    if not all(lv in quantiles for lv in _LEVELS):
        return None
    lead = doc.get("hypothesis") or {}
    return CalibrationRecord(quantiles, float(doc.get("rate_ratio", math.nan)),
                             float(flight["true_rul"]), lead.get("name"),
                             float(lead.get("weight", 1.0)))


def calibration_records(traces: Iterable[Mapping[str, Any]], per_run: int
                        ) -> tuple[dict[str, list[CalibrationRecord]], dict[str, int]]:
    """Per mode whose filter predicted: the records of up to ``per_run`` predictions per
    progressive run, evenly spaced from its first alarm to its failure; and the runs per mode."""
    records: dict[str, list[CalibrationRecord]] = defaultdict(list)
    runs: dict[str, int] = defaultdict(int)
    for trace in traces:
        if trace["mode"] not in PROGRESSIVE or trace.get("failure") is None:
            continue
        alarm = _first_alarm(trace)
        if alarm is None:
            continue
        flights = [f for f in trace["flights"]
                   if alarm <= f["index"] < trace["failure"] and f.get("rul")]
        if not flights:
            continue
        pick = np.unique(np.linspace(0, len(flights) - 1, min(per_run, len(flights)))
                         .round().astype(int))
        modes = set()
        for i in pick:
            rec = _record(flights[i])
            if rec is not None and flights[i]["fault_mode"]:
                records[flights[i]["fault_mode"]].append(rec)
                modes.add(flights[i]["fault_mode"])
        for m in modes:
            runs[m] += 1
    return dict(records), dict(runs)


def calibrate_model(model_doc: dict[str, Any], traces: Sequence[Mapping[str, Any]], *,
                    per_run: int = 20, edges: tuple[float, ...] = (0.5, 2.0),
                    min_group: int = 30, replays: Sequence[Mapping[str, Any]] = (),
                    weight_split: float | None = None
                    ) -> tuple[dict[str, Any], dict[str, Any]]:
    """The model document with each mode's layer fitted on ``traces``, and a report;
    ``replays`` (the campaigns replayed) go into each layer's notes."""
    model = read_model_document(model_doc)
    if any(s.band_calibration is not None for s in model.measurement.values()):
        raise ValueError("the model already has a calibration layer: give the uncalibrated one")
    records, runs = calibration_records(traces, per_run)
    report: dict[str, Any] = {}
    payload = _unwrap(model_doc)
    for mode in model.measurement:
        recs = records.get(mode, [])
        if len(recs) < min_group:
            report[mode] = {"records": len(recs), "fitted": False}
            continue
        prognoser = model.measurement[mode].prognoser
        bank = prognoser.rate_hypotheses if prognoser is not None else ()
        layer = replace(fit_band_calibration(recs, edges=edges, min_group=min_group,
                                             n_runs=runs.get(mode, 0),
                                             hypotheses=tuple(h.name for h in bank),
                                             weight_split=weight_split),
                        notes={"replays": [dict(r) for r in replays], "per_run": per_run})
        payload["measurement"][mode]["band_calibration"] = layer.to_dict()
        report[mode] = {"records": len(recs), "runs": runs.get(mode, 0), "fitted": True,
                        **layer.to_dict()}
    read_model_document(model_doc)  # the document still reads
    return model_doc, report


def add_calibrate_arguments(parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
    parser.add_argument("--evaluation", required=True, action="append",
                        help="evaluation directory (or evaluation.json) of the uncalibrated "
                        "model on a calibration design campaign; repeatable")
    parser.add_argument("--model-json", required=True, help="the uncalibrated model document")
    parser.add_argument("--out", required=True, help="the calibrated model document to write")
    parser.add_argument("--per-run", type=int, default=20,
                        help="predictions per run (evenly spaced from alarm to failure)")
    parser.add_argument("--min-group", type=int, default=30,
                        help="fewest records for a group's own margins (else the mode's)")
    parser.add_argument("--weight-split", type=float, default=DEFAULT_WEIGHT_SPLIT,
                        help="with a bank: calibrate leads below this weight apart from the "
                        f"confident ones (default {DEFAULT_WEIGHT_SPLIT:g}; 0: no split)")
    return parser


def _traces(paths: Sequence[str], model_doc: Mapping[str, Any]
            ) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """The replays' traces, and what each replayed campaign was (its directory left out)."""
    design = model_doc.get("design") or {}
    out: list[dict[str, Any]] = []
    campaigns: list[dict[str, Any]] = []
    for p in paths:
        path = Path(p) / "evaluation.json" if Path(p).is_dir() else Path(p)
        doc = json.loads(path.read_text())
        camp = doc.get("campaign") or {}
        if design and (camp.get("kind"), camp.get("seed")) == (design.get("kind"),
                                                               design.get("seed")):
            raise ValueError(f"{path}: replays of the model's own design campaign (seed "
                             f"{camp.get('seed')}); calibrate on design runs kept apart")
        out += doc["patterns"]
        campaigns.append({k: v for k, v in camp.items()
                          if k in ("kind", "seed", "scale", "render_every", "patterns",
                                   "flights")})
    return out, campaigns


def run_calibrate(args: argparse.Namespace, settings: object = None) -> int:
    if args.per_run < 1 or args.min_group < 1:
        raise ValueError("--per-run and --min-group must be >= 1")
    if not 0.0 <= args.weight_split <= 1.0:
        raise ValueError("--weight-split must lie in [0, 1] (0: no split)")
    model_doc = json.loads(Path(args.model_json).read_text())
    traces, replays = _traces(args.evaluation, model_doc)
    doc, report = calibrate_model(model_doc, traces, per_run=args.per_run,
                                  min_group=args.min_group, replays=replays,
                                  weight_split=args.weight_split or None)
    out = Path(args.out)
    tmp = out.with_suffix(".part")
    tmp.write_text(json.dumps(doc, sort_keys=True, separators=(",", ":")) + "\n")
    tmp.replace(out)
    for mode, r in report.items():
        if not r["fitted"]:
            print(f"{mode}: {r['records']} records, not fitted")
            continue
        groups = ", ".join(f"{n}: {_fmt(m)}" for n, m in zip(r["counts"], r["margins"],
                                                            strict=True))
        print(f"{mode}: {r['records']} records from {r['runs']} runs; pooled "
              f"{_fmt(r['pooled'])}; by rate group (n: 50 %, 90 % as (lower, upper)) {groups}")
        if r.get("weight_split") is not None:
            halves = ", ".join(f"{n}: {_fmt(m)}" for n, m in zip(r["split_counts"],
                                                                r["split_margins"], strict=True))
            print(f"  leads below weight {r['weight_split']:g} apart (ambiguous, confident per "
                  f"hypothesis): {halves}")
    print(f"calibrated model written to {out}")
    return 0


def _fmt(margins: Sequence[Sequence[float]]) -> str:
    """Each band's (lower, upper) margins."""
    return " ".join(f"({lo:+.2f}, {hi:+.2f})" for _, lo, hi in margins)
