"""Fit baselines and detector on a design campaign, evaluate detection on a verification one.

The command is ``python -m server.evaluation.detection --design DIR --verification DIR``. Time
base: flights; the detection time is reported in percent of the fault's life ``(detected -
onset) / (failure - onset)``.

Honesty rules kept here: the baselines, the healthy bands and every threshold come from the
design campaign only; the verification campaign is only read to be scored. The bands are
learned on *out-of-fold* residuals (leave-one-aircraft-out baselines), so that the design
aircraft are as unseen to the baseline as the verification ones will be.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from server.vocabulary import alarming_positions

from .baselines import FleetBaseline
from .dataset import Campaign, FlightRecord, Pattern, healthy_flights, reads_rod_ends_as_pair
from .detection import UNITS, DetectionState, FaultDetector
from .features import AIRCRAFT_FEATURES
from .metrics import event_rate

__all__ = [
    "FlightRecord",
    "Pattern",
    "Campaign",
    "healthy_flights",
    "fit_detection",
    "healthy_alarm_rate",
    "DetectionModel",
    "PatternOutcome",
    "evaluate",
    "summarise",
    "format_report",
]


@dataclass
class DetectionModel:
    """What detection needs at run time: the baseline and the detector (JSON together);
    ``design_false_alarms``: the alarms its bands raised on the design's healthy lives
    (:func:`healthy_alarm_rate`, not part of the document)."""

    baseline: FleetBaseline
    detector: FaultDetector
    design_false_alarms: dict[str, Any] | None = None

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
    tails_of = [a for a, s in seqs for _ in s]  # each flight's aircraft: its units
    proto = baseline or FleetBaseline()
    final = FleetBaseline(proto.covariates, ridge=proto.ridge, outlier_k=proto.outlier_k,
                          min_evidence=proto.min_evidence, within_units=proto.within_units,
                          log_features=proto.log_features).fit(all_flights, tails_of)
    tails = sorted({a for a, _ in seqs})
    oof: list[np.ndarray] = []
    for tail in tails:
        train = [f for a, s in seqs if a != tail for f in s]
        if len(train) < 3:
            continue
        b = FleetBaseline(proto.covariates, ridge=proto.ridge, outlier_k=proto.outlier_k,
                          min_evidence=proto.min_evidence, within_units=proto.within_units,
                          log_features=proto.log_features)
        b.fit(train, [a for a, s in seqs if a != tail for _ in s])
        oof += [b.zscore_matrix(s) for a, s in seqs if a == tail]
    det = detector or FaultDetector()
    sequences = oof if oof else [final.zscore_matrix(s) for _, s in seqs]
    det.fit(sequences, AIRCRAFT_FEATURES)
    return DetectionModel(final, det, healthy_alarm_rate(det, sequences))


def healthy_alarm_rate(detector: FaultDetector, sequences: Sequence[np.ndarray],
                       level: float = 0.90) -> dict[str, Any]:
    """Alarm events per unit-flight on healthy sequences (n_flights, AIRCRAFT_FEATURES) of
    residuals, each unit at risk until its first alarm: the realised rate beside the stated
    ``false_alarm_rate``, with its exact ``level`` interval."""
    events = unit_flights = 0
    for seq in sequences:
        for unit in UNITS:
            names = [n for n in AIRCRAFT_FEATURES if n.split(".", 1)[0] == unit
                     and n in detector.feature_names_]
            cols = [AIRCRAFT_FEATURES.index(n) for n in names]
            conf = detector.confidence_sequence(seq[:, cols], names).max(axis=1)
            hits = np.flatnonzero(conf >= detector.alarm_confidence)
            events += int(hits.size > 0)
            unit_flights += int(hits[0]) + 1 if hits.size else seq.shape[0]
    return {**event_rate(events, unit_flights, level), "level": level,
            "stated_rate": detector.false_alarm_rate}


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
    return alarming_positions(p.mode, p.position, pair_rod_ends=reads_rod_ends_as_pair(p))


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
