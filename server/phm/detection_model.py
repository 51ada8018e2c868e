"""The detection model fitted on a design campaign: fleet baselines and the detector's bands.

Honesty rules kept here: the baselines, the healthy bands and every threshold come from the
design campaign only. The bands are learned on *out-of-fold* residuals (leave-one-aircraft-out
baselines), so that the design aircraft are as unseen to the baseline as the verification ones
will be. Training (:mod:`server.phm.training`) fits it; scoring it on a verification campaign
is the evaluation's (:mod:`server.evaluation.evaluate_detection`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from .baselines import FleetBaseline
from .dataset import Campaign, healthy_flights
from .detection import UNITS, DetectionState, FaultDetector, first_alarms, new_states
from .features import AIRCRAFT_FEATURES
from .metrics import event_rate

__all__ = ["DetectionModel", "fit_detection", "healthy_alarm_rate"]


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
        return new_states(self.detector, UNITS)


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
    evidence: list[np.ndarray] = []
    for tail in tails:
        train = [f for a, s in seqs if a != tail for f in s]
        if len(train) < 3:
            continue
        b = FleetBaseline(proto.covariates, ridge=proto.ridge, outlier_k=proto.outlier_k,
                          min_evidence=proto.min_evidence, within_units=proto.within_units,
                          log_features=proto.log_features)
        b.fit(train, [a for a, s in seqs if a != tail for _ in s])
        oof += [b.zscore_matrix(s) for a, s in seqs if a == tail]
        evidence += [b.evidence_matrix(s) for a, s in seqs if a == tail]
    det = detector or FaultDetector()
    if not oof:
        evidence = [final.evidence_matrix(s) for _, s in seqs]
    sequences = oof if oof else [final.zscore_matrix(s) for _, s in seqs]
    det.fit(sequences, AIRCRAFT_FEATURES, evidence)
    return DetectionModel(final, det, healthy_alarm_rate(det, sequences, evidence=evidence))


def healthy_alarm_rate(detector: FaultDetector, sequences: Sequence[np.ndarray],
                       level: float = 0.90,
                       evidence: Sequence[np.ndarray] | None = None) -> dict[str, Any]:
    """Alarm events per unit-flight on healthy sequences (n_flights, AIRCRAFT_FEATURES) of
    residuals, each aircraft's units judged together as the chain judges them
    (:func:`~server.phm.detection.first_alarms`) and each unit at risk until its first alarm:
    the realised rate beside the stated ``false_alarm_rate``, with its exact ``level``
    interval. ``evidence``: the flights' evidence weights, same shapes (None: typical)."""
    names = [n for n in AIRCRAFT_FEATURES if n in detector.feature_names_]
    cols = [AIRCRAFT_FEATURES.index(n) for n in names]
    events = unit_flights = 0
    for h, seq in enumerate(sequences):
        ev = None if evidence is None else evidence[h][:, cols]
        first = first_alarms(detector, seq[:, cols], names, ev)
        for unit in UNITS:
            if unit not in first:
                continue
            hit = first[unit]
            events += int(hit is not None)
            unit_flights += seq.shape[0] if hit is None else hit + 1
    return {**event_rate(events, unit_flights, level), "level": level,
            "stated_rate": detector.false_alarm_rate}
