"""Fit baselines and detector on a design campaign, evaluate detection on a verification one.

Usage::

    python -m server.phm.evaluate_detection --design DIR --verification DIR [--jobs 2]

Campaign directories follow the ``ema-campaign/1`` manifest written by ``sim-worker campaign``
(``DIR/manifest.json`` and ``DIR/flights/<tail>/<flight>.parquet``). Time base: flights; the
detection time is reported in percent of the fault's life ``(detected - onset) / (failure -
onset)``.

Honesty rules kept here: the baselines, the healthy bands and every threshold come from the
design campaign only; the verification campaign is only read to be scored. The bands are
learned on *out-of-fold* residuals (leave-one-aircraft-out baselines), so that the design
aircraft are as unseen to the baseline as the verification ones will be.

Reading Parquet needs ``pyarrow`` (a project dependency); it is imported lazily inside
:func:`read_flight_channels` only, so the algorithm modules stay numpy/scipy/scikit-learn.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
from collections.abc import Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path
from typing import Any

import numpy as np

from server.flightlog import parse_metadata

from .baselines import FleetBaseline
from .detection import UNITS, DetectionState, FaultDetector
from .features import (
    AIRCRAFT_FEATURES,
    FEATURE_VERSION,
    FeatureConfig,
    FeatureSummary,
    FlightFeatures,
    flight_features,
)

__all__ = [
    "FlightRecord",
    "Pattern",
    "Campaign",
    "read_flight_channels",
    "load_campaign",
    "healthy_flights",
    "fit_detection",
    "DetectionModel",
    "PatternOutcome",
    "evaluate",
    "format_report",
    "main",
]

PROGRESSIVE = ("TTS", "DMD", "MTEL", "MTWEAR", "REWEAR")


@dataclass
class FlightRecord:
    """One flight of a pattern with its features and labels (labels never reach the PHM)."""

    flight: str
    index: int
    severity: float
    severity_norm: float
    true_rul_flights: float | None
    ground_temp_c: float | None
    features: FlightFeatures
    started_at: datetime | None = None  # take-off time, from the flight log's metadata


@dataclass
class Pattern:
    id: str
    aircraft: str
    mode: str
    position: str | None
    onset_flight: int | None
    failure_flight: int | None
    flights: list[FlightRecord] = field(default_factory=list)
    base: str | None = None  # the aircraft's home base


@dataclass
class Campaign:
    kind: str
    seed: int
    patterns: list[Pattern]
    aircraft: list[dict[str, Any]]


def read_flight_channels(path: str | os.PathLike[str]) -> dict[str, np.ndarray]:
    """All channels of a flight-log v1 Parquet file as float64 arrays (pyarrow, lazy import)."""
    import pyarrow.parquet as pq

    table = pq.read_table(path)
    return {n: table.column(n).to_numpy().astype(np.float64) for n in table.column_names}


def _features_of(args: tuple[str, float | None, FeatureConfig]) -> dict[str, Any]:
    path, ground, cfg = args
    ch = read_flight_channels(path)
    return flight_features(ch, config=cfg, ground_temp_c=ground).to_dict()


def read_started_at(path: str | os.PathLike[str]) -> datetime | None:
    """Take-off time (UTC) from a flight-log Parquet file's metadata, read from the footer
    only and validated as the service validates an upload (:func:`parse_metadata`); None for a
    file without metadata."""
    import pyarrow.parquet as pq

    meta = pq.read_schema(path).metadata or {}
    if b"started_at" not in meta:
        return None
    return parse_metadata({k.decode(): v.decode() for k, v in meta.items()}).started_at


def _ff_from_dict(d: Mapping[str, Any]) -> FlightFeatures:
    summ = {k: FeatureSummary(float(v["value"]), float(v["dispersion"]), int(v["n_valid"]))
            for k, v in d["summaries"].items()}
    cond = {p: {k: float(v) for k, v in c.items()} for p, c in d["conditions"].items()}
    return FlightFeatures(summ, cond)


def load_campaign(directory: str | os.PathLike[str], *, config: FeatureConfig | None = None,
                  jobs: int = 1, cache: bool = True) -> Campaign:
    """Read a campaign manifest and compute the features of every flight.

    With ``cache`` the features are stored beside the manifest in ``phm_features.json`` (keyed
    by file) and reused when present and computed with the same configuration.
    """
    cfg = config or FeatureConfig()
    root = Path(directory)
    manifest = json.loads((root / "manifest.json").read_text())
    if manifest.get("format") != "ema-campaign/1":
        raise ValueError(f"{root}: not an ema-campaign/1 manifest")
    cache_path = root / "phm_features.json"
    cfg_key = f"{FEATURE_VERSION} {cfg!r}"
    cached: dict[str, Any] = {}
    if cache and cache_path.exists():
        doc = json.loads(cache_path.read_text())
        if doc.get("config") == cfg_key:
            cached = doc["flights"]
    todo: list[tuple[str, float | None]] = []
    for pat in manifest["patterns"]:
        for fl in pat["flights"]:
            if fl["file"] not in cached:
                todo.append((fl["file"], fl.get("ground_temp_c")))
    if todo:
        args = [(str(root / f), g, cfg) for f, g in todo]
        if jobs > 1:
            with ProcessPoolExecutor(max_workers=jobs) as ex:
                results = list(ex.map(_features_of, args, chunksize=4))
        else:
            results = [_features_of(a) for a in args]
        for (f, _), r in zip(todo, results, strict=True):
            cached[f] = r
        if cache:
            tmp = cache_path.with_suffix(".tmp")
            tmp.write_text(json.dumps({"config": cfg_key, "flights": cached}))
            tmp.replace(cache_path)
    bases = {str(a.get("tail")): a.get("base") for a in manifest.get("aircraft", [])}
    patterns = []
    for pat in manifest["patterns"]:
        recs = [FlightRecord(str(fl["flight"]), int(fl["index"]), float(fl.get("severity", 0.0)),
                             float(fl.get("severity_norm", 0.0)),
                             None if fl.get("true_rul_flights") is None
                             else float(fl["true_rul_flights"]),
                             fl.get("ground_temp_c"), _ff_from_dict(cached[fl["file"]]),
                             read_started_at(root / fl["file"]))
                for fl in sorted(pat["flights"], key=lambda f: int(f["index"]))]
        patterns.append(Pattern(str(pat["id"]), str(pat["aircraft"]), str(pat["mode"]),
                                pat.get("position"), pat.get("onset_flight"),
                                pat.get("failure_flight"), recs, bases.get(str(pat["aircraft"]))))
    return Campaign(str(manifest.get("kind")), int(manifest.get("seed", 0)), patterns,
                    list(manifest.get("aircraft", [])))


def _is_healthy(p: Pattern, r: FlightRecord) -> bool:
    if p.mode == "healthy":
        return True
    return p.onset_flight is not None and r.index < int(p.onset_flight)


def healthy_flights(campaign: Campaign) -> list[tuple[str, list[FlightFeatures]]]:
    """Healthy flight sequences ``(aircraft, flights in order)``: healthy patterns and the
    pre-onset flights of fault patterns."""
    out = []
    for p in campaign.patterns:
        seq = [r.features for r in p.flights if _is_healthy(p, r)]
        if seq:
            out.append((p.aircraft, seq))
    return out


@dataclass
class DetectionModel:
    """What detection needs at run time: the baseline and the detector (JSON together)."""

    baseline: FleetBaseline
    detector: FaultDetector

    def to_dict(self) -> dict[str, Any]:
        return {"format": "ema-detection-model/1", "baseline": self.baseline.to_dict(),
                "detector": self.detector.to_dict()}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> DetectionModel:
        if d.get("format") != "ema-detection-model/1":
            raise ValueError("not an ema-detection-model/1 document")
        return cls(FleetBaseline.from_dict(d["baseline"]), FaultDetector.from_dict(d["detector"]))

    def new_states(self) -> dict[str, DetectionState]:
        return {u: self.detector.new_state(u) for u in UNITS}


def fit_detection(design: Campaign, *, detector: FaultDetector | None = None,
                  baseline: FleetBaseline | None = None) -> DetectionModel:
    """Baselines on all healthy design flights; detector bands on out-of-fold residuals."""
    seqs = healthy_flights(design)
    all_flights = [f for _, s in seqs for f in s]
    proto = baseline or FleetBaseline()
    final = FleetBaseline(proto.covariates, ridge=proto.ridge, outlier_k=proto.outlier_k,
                          min_evidence=proto.min_evidence).fit(all_flights)
    tails = sorted({a for a, _ in seqs})
    oof: list[np.ndarray] = []
    for tail in tails:
        train = [f for a, s in seqs if a != tail for f in s]
        if len(train) < 3:
            continue
        b = FleetBaseline(proto.covariates, ridge=proto.ridge, outlier_k=proto.outlier_k,
                          min_evidence=proto.min_evidence)
        b.fit(train)
        oof += [b.zscore_matrix(s) for a, s in seqs if a == tail]
    det = detector or FaultDetector()
    det.fit(oof if oof else [final.zscore_matrix(s) for _, s in seqs], AIRCRAFT_FEATURES)
    return DetectionModel(final, det)


@dataclass
class PatternOutcome:
    id: str
    aircraft: str
    mode: str
    position: str | None
    onset: int | None
    failure: int | None
    detected_index: int | None  # flight index of the first alarm of the faulty unit(s)
    false_alarms: int  # alarms raised before onset (or at all, for healthy patterns)
    other_unit_alarms: int  # alarms on units other than the faulty one after onset
    alarm_features: list[str]
    n_flights: int

    @property
    def detection_pct_life(self) -> float:
        if self.detected_index is None or self.onset is None or self.failure is None:
            return math.nan
        life = max(self.failure - self.onset, 1)
        return 100.0 * (self.detected_index - self.onset) / life

    @property
    def flights_after_onset(self) -> float:
        if self.detected_index is None or self.onset is None:
            return math.nan
        return float(self.detected_index - self.onset)


def _faulty_units(p: Pattern) -> set[str]:
    if p.position is None:
        return set()
    units = {p.position}
    if p.position in ("WL1", "WL2"):
        units.add("WL")
    return units


def run_pattern(model: DetectionModel, p: Pattern) -> PatternOutcome:
    """Run detection flight by flight over one pattern (states carried as in service)."""
    states = model.new_states()
    faulty = _faulty_units(p)
    onset = p.onset_flight if p.mode != "healthy" else None
    detected: int | None = None
    false_alarms = 0
    other = 0
    feats: list[str] = []
    for r in p.flights:
        z = model.baseline.zscores(r.features)
        for u, st in states.items():
            res = model.detector.update(st, z)
            if not res.new_alarm:
                continue
            pre_onset = onset is None or r.index < int(onset)
            if pre_onset:
                false_alarms += 1
            elif u in faulty:
                if detected is None:
                    detected = r.index
                    feats = res.alarm_features
            else:
                other += 1
    return PatternOutcome(p.id, p.aircraft, p.mode, p.position, p.onset_flight, p.failure_flight,
                          detected, false_alarms, other, feats, len(p.flights))


def evaluate(model: DetectionModel, campaign: Campaign) -> list[PatternOutcome]:
    return [run_pattern(model, p) for p in campaign.patterns]


def summarise(outcomes: Sequence[PatternOutcome]) -> list[dict[str, Any]]:
    """Per fault mode: patterns, detection rate, detection time (% of life), false alarms."""
    modes = sorted({o.mode for o in outcomes}, key=lambda m: (m != "healthy", m))
    rows = []
    for m in modes:
        os_ = [o for o in outcomes if o.mode == m]
        det = [o for o in os_ if o.detected_index is not None]
        pct = np.array([o.detection_pct_life for o in det], dtype=np.float64)
        aft = np.array([o.flights_after_onset for o in det], dtype=np.float64)
        healthy_flights = sum(o.n_flights if m == "healthy" else
                              (o.onset or 0) for o in os_)
        rows.append({
            "mode": m, "patterns": len(os_),
            "detected": len(det) if m != "healthy" else None,
            "rate": (len(det) / len(os_)) if m != "healthy" and os_ else None,
            "pct_life_median": float(np.median(pct)) if pct.size else None,
            "pct_life_max": float(np.max(pct)) if pct.size else None,
            "flights_after_onset_max": float(np.max(aft)) if aft.size else None,
            "false_alarms": sum(o.false_alarms for o in os_),
            "healthy_flights": healthy_flights,
            "other_unit_alarms": sum(o.other_unit_alarms for o in os_),
        })
    return rows


def _fmt(v: Any, spec: str = ".1f") -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "-"
    return format(v, spec)


def format_report(rows: Sequence[Mapping[str, Any]]) -> str:
    """Markdown table of :func:`summarise` rows."""
    lines = ["| mode | patterns | detected | rate | detection time median / max [% life] | "
             "max flights after onset | false alarms / healthy flights | alarms on other units |",
             "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(
            f"| {r['mode']} | {r['patterns']} | {_fmt(r['detected'], 'd')} | "
            f"{_fmt(None if r['rate'] is None else 100 * r['rate'], '.0f')}"
            f"{'' if r['rate'] is None else ' %'} | "
            f"{_fmt(r['pct_life_median'])} / {_fmt(r['pct_life_max'])} | "
            f"{_fmt(r['flights_after_onset_max'], '.0f')} | "
            f"{r['false_alarms']} / {r['healthy_flights']} | {r['other_unit_alarms']} |")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--design", required=True, help="design campaign directory")
    ap.add_argument("--verification", required=True, help="verification campaign directory")
    ap.add_argument("--jobs", type=int, default=min(2, os.cpu_count() or 1))
    ap.add_argument("--model-out", help="write the fitted detection model (JSON) here")
    ap.add_argument("--no-cache", action="store_true", help="do not cache features")
    args = ap.parse_args(argv)
    design = load_campaign(args.design, jobs=args.jobs, cache=not args.no_cache)
    model = fit_detection(design)
    if args.model_out:
        Path(args.model_out).write_text(json.dumps(model.to_dict(), indent=1))
    verification = load_campaign(args.verification, jobs=args.jobs, cache=not args.no_cache)
    outcomes = evaluate(model, verification)
    rows = summarise(outcomes)
    n_air = len({p.aircraft for p in verification.patterns})
    print(f"design: {args.design} ({len(design.patterns)} patterns); verification: "
          f"{args.verification} ({len(verification.patterns)} patterns, {n_air} aircraft)")
    print(f"alarm at separation confidence {model.detector.alarm_confidence} "
          f"(= {model.detector.z_alarm:.2f} standard errors beyond the healthy band), windows "
          f"{list(model.detector.windows)} flights")
    print(format_report(rows))
    missed = [o for o in outcomes if o.mode != "healthy" and o.detected_index is None]
    for o in missed:
        print(f"missed: {o.id} {o.mode} {o.aircraft}/{o.position}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
