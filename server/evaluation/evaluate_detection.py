"""Detection alone, scored: a fitted detection model run over a campaign's patterns.

The command is ``python -m server.evaluation.detection --design DIR --verification DIR``. Time
base: flights; the detection time is reported in percent of the fault's life ``(detected -
onset) / (failure - onset)``. The model comes fitted on the design campaign
(:func:`server.phm.detection_model.fit_detection`); the verification campaign is only read to
be scored.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from server.phm.dataset import Campaign, Pattern, reads_rod_ends_as_pair
from server.phm.detection import update_units
from server.phm.detection_model import DetectionModel
from server.vocabulary import alarming_positions

__all__ = ["PatternOutcome", "run_pattern", "evaluate", "summarise", "format_report"]


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
        evidence = model.baseline.evidence_weights(r.features)
        for u, res in update_units(model.detector, states, z, evidence=evidence).items():
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
