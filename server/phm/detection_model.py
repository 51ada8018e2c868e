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
from .features import AIRCRAFT_FEATURES, FlightFeatures
from .metrics import event_rate

__all__ = ["DetectionModel", "fit_detection", "healthy_alarm_rate", "out_of_fold_residuals"]


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
    proto = baseline or FleetBaseline()
    final = _unfitted_like(proto).fit([f for _, s in seqs for f in s],
                                      [a for a, s in seqs for _ in s])
    oof = out_of_fold_residuals(seqs, proto)
    det = detector or FaultDetector()
    if oof:
        sequences, evidence = [z for _, z, _ in oof], [e for _, _, e in oof]
    else:
        sequences = [final.zscore_matrix(s) for _, s in seqs]
        evidence = [final.evidence_matrix(s) for _, s in seqs]
    det.fit(sequences, AIRCRAFT_FEATURES, evidence)
    return DetectionModel(final, det, healthy_alarm_rate(det, sequences, evidence=evidence))


def out_of_fold_residuals(seqs: Sequence[tuple[str, Sequence[FlightFeatures]]],
                          proto: FleetBaseline) -> list[tuple[int, np.ndarray, np.ndarray]]:
    """``(index in seqs, z, evidence)`` of every healthy sequence ``(aircraft, flights)``, each
    from a baseline with ``proto``'s settings fitted without its aircraft (aircraft in sorted
    order; none whose others hold fewer than 3 flights)."""
    out = []
    for tail in sorted({a for a, _ in seqs}):
        train = [(a, f) for a, s in seqs if a != tail for f in s]
        if len(train) < 3:
            continue
        b = _unfitted_like(proto).fit([f for _, f in train], [a for a, _ in train])
        out += [(h, b.zscore_matrix(s), b.evidence_matrix(s))
                for h, (a, s) in enumerate(seqs) if a == tail]
    return out


def _unfitted_like(proto: FleetBaseline) -> FleetBaseline:
    return FleetBaseline(proto.covariates, ridge=proto.ridge, outlier_k=proto.outlier_k,
                         min_evidence=proto.min_evidence, within_units=proto.within_units,
                         log_features=proto.log_features)


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
