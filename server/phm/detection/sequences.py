"""The online judge (:mod:`.judge`) over whole flight sequences at once, vectorised: what
:func:`~server.phm.detection.judge.update_units` says on every flight of a sequence, for
learning the bands (:func:`healthy_statistics`) and for the healthy alarm rate
(:func:`first_alarms`).

A sequence's columns are the features of the units judged together (an aircraft's, for the
design's healthy flights), so the winglet pair's rule (:mod:`.pair`) applies as it does online:
a feature whose evidence is left to the partner raises no alarm on that flight.
``tests/phm/test_judge.py`` holds the two forms equal.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from scipy.special import ndtr

from .config import unit_of
from .pair import held_sequence, is_pair_coupled, level_sequence
from .statistics import running_statistics, self_referenced_sequence

if TYPE_CHECKING:  # the detector's fit calls this module: its type only
    from .detector import FaultDetector

__all__ = ["SequenceJudgement", "confidence_sequence", "first_alarms", "healthy_statistics",
           "judge_sequence"]


@dataclass(frozen=True)
class SequenceJudgement:
    """What the online judge says on every flight of a sequence, (n_flights, n_features)
    arrays in the sequence's column order."""

    #: each feature's confidence, as :attr:`DetectionResult.confidence`
    confidence: np.ndarray
    #: where a feature's evidence is left to the partner drive, as :attr:`DetectionResult.held`
    held: np.ndarray
    alarm_confidence: float

    @property
    def firing(self) -> np.ndarray:
        """The features that raise their unit's alarm: confidence at ``alarm_confidence`` or
        above, evidence not left to the partner."""
        return (self.confidence >= self.alarm_confidence) & ~self.held


def judge_sequence(detector: FaultDetector, z: np.ndarray, feature_names: Sequence[str],
                   evidence: np.ndarray | None = None) -> SequenceJudgement:
    """Every flight of a sequence of standardised residuals ``z`` (n_flights, n_features in
    ``feature_names`` order), the units with a column judged together; ``evidence``: the
    flights' evidence weights, same shape (None: typical)."""
    detector.check_fitted()
    idx = [detector.feature_names_.index(n) for n in feature_names]
    z_self = _self_referenced(detector, z, feature_names, evidence)
    conf = np.zeros(z_self.shape)
    min_w = np.array([detector.min_window(n) for n in feature_names])
    n_seen = np.cumsum(np.isfinite(z_self), axis=0)
    for k, w, s in _window_statistics(detector, z_self, feature_names):
        c = ndtr(s - detector.band_[idx, k][np.newaxis, :])
        # judged once full, and only the windows allowed to alarm, as online
        allowed = (w >= min_w)[np.newaxis, :] & (n_seen >= np.maximum(w, min_w)[np.newaxis, :])
        conf = np.fmax(conf, np.where(np.isfinite(c) & allowed, c, 0.0))
    return SequenceJudgement(conf, _held(detector, z_self, feature_names),
                             detector.alarm_confidence)


def confidence_sequence(detector: FaultDetector, z: np.ndarray, feature_names: Sequence[str],
                        evidence: np.ndarray | None = None) -> np.ndarray:
    """The confidences of :func:`judge_sequence` (n_flights, n_features)."""
    return judge_sequence(detector, z, feature_names, evidence).confidence


def first_alarms(detector: FaultDetector, z: np.ndarray, feature_names: Sequence[str],
                 evidence: np.ndarray | None = None) -> dict[str, int | None]:
    """Unit -> the row of its first alarm in the sequence (None: none), for every unit with a
    column: the flight on which the online judge raises it (``new_alarm``)."""
    firing = judge_sequence(detector, z, feature_names, evidence).firing
    out: dict[str, int | None] = {}
    for unit in dict.fromkeys(unit_of(n) for n in feature_names):
        cols = [j for j, n in enumerate(feature_names) if unit_of(n) == unit]
        rows = np.flatnonzero(firing[:, cols].any(axis=1))
        out[unit] = int(rows[0]) if rows.size else None
    return out


def healthy_statistics(detector: FaultDetector, healthy_sequences: Sequence[np.ndarray],
                       feature_names: Sequence[str],
                       evidence: Sequence[np.ndarray] | None = None
                       ) -> list[list[np.ndarray]]:
    """The judged statistics of healthy sequences, ``[window][feature]`` -> 1-D array of
    every flight's oriented ``S_w`` (``|S_w|`` for a two-sided feature) once the window is
    full, held through flights without a value; -inf on a flight whose evidence the pair rule
    leaves to the partner (it raises no alarm there). Windows shorter than a feature's
    ``min_windows`` count from ``w`` flights on. Needs the fitted offsets (``within_std_``,
    ``between_std_``, ``evidence_variance_``), not the bands: the detector's fit calls it.
    ``evidence``: each flight's evidence weights (None: every flight typical)."""
    names = list(feature_names)
    min_w = np.array([detector.min_window(n) for n in names])
    out: list[list[list[np.ndarray]]] = [[[] for _ in names] for _ in detector.windows]
    for h, q in enumerate(healthy_sequences):
        z_self = _self_referenced(detector, q, names, None if evidence is None else evidence[h])
        held = _held(detector, z_self, names)
        n_seen = np.cumsum(np.isfinite(z_self), axis=0)
        for k, w, s in _window_statistics(detector, z_self, names):
            need = np.where(w >= min_w, np.maximum(w, min_w), w)[np.newaxis, :]
            judged = (n_seen >= need) & np.isfinite(s)
            s = np.where(held, -math.inf, s)
            for j in range(len(names)):
                out[k][j].append(s[judged[:, j], j])
    return [[np.concatenate(c) if c else np.empty(0) for c in per_w] for per_w in out]


def _self_referenced(detector: FaultDetector, z: np.ndarray, names: Sequence[str],
                     evidence: np.ndarray | None) -> np.ndarray:
    """Self-referenced residuals of one sequence, each flight's scatter widened by its
    evidence's share."""
    idx = [detector.feature_names_.index(n) for n in names]
    z = np.asarray(z, dtype=np.float64).reshape(-1, len(idx))
    extra = None if evidence is None else detector.evidence_extra(
        np.asarray(evidence, dtype=np.float64).reshape(z.shape), names)
    return self_referenced_sequence(z, detector.within_std_[idx], detector.between_std_[idx],
                                    detector.reference_flights, extra)


def _window_statistics(detector: FaultDetector, z_self: np.ndarray, names: Sequence[str]
                       ) -> Iterator[tuple[int, int, np.ndarray]]:
    """``(k, w, S_w)`` of every window: the running statistic along each fault's direction
    (``|S_w|`` for a two-sided feature), (n_flights, n_features)."""
    d = detector.directions_of(names)[np.newaxis, :]
    for k, w in enumerate(detector.windows):
        s = running_statistics(detector.clipped(z_self, w), w, median=detector.uses_median(w))
        yield k, w, np.where(d == 0, np.abs(s), d * s)


def _held(detector: FaultDetector, z_self: np.ndarray, names: Sequence[str]) -> np.ndarray:
    """Where the pair rule leaves a feature's evidence to the partner drive (n_flights,
    n_features), from each coupled feature's level over the judge's history."""
    keep = max(detector.windows)
    levels = np.full(z_self.shape, -math.inf)
    for j, n in enumerate(names):
        if is_pair_coupled(n):
            levels[:, j] = level_sequence(z_self[:, j], detector.direction(n), keep)
    return held_sequence(levels, names)
