"""A second mode named by its own feature: beyond what the leading mode's fault alone gives it.

A fault moves more than its own feature: a thread-to-thread short raises the motor's current
and with it ``F_DMD``, the dynamic-model deviation. Taught on single faults, the one-vs-rest SVM
learned that a high ``F_TTS`` argues against DMD, so a DMD beside a leading TTS keeps a low own
probability (:mod:`.modes`). Its own feature still tells them apart: on the unit's flights in
alarm, a mode's own feature (pooled since the alarm as the chain pools the class evidence)
above the values the leading mode's faults alone gave it in the design names it present.

The limit per leading mode ``L`` and mode ``m`` is a quantile of ``m``'s pooled own feature over
the design's single faults of ``L``, on their flights in alarm (the classifier's training
rows, :func:`server.phm.training.training_rows`): the design's cross-talk. The quantile is
chosen on other design seeds (``bench/mode_sets.py``, docs/TUNING.md ``CROSSTALK``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.signal import lfilter

from server.vocabulary import GENERIC_FEATURES, OWN_FEATURE, PROGRESSIVE

__all__ = ["CrossTalk", "CROSSTALK_QUANTILE", "fit_crosstalk", "pooled_means"]

#: the quantile of the design's cross-talk a second mode's pooled own feature must exceed:
#: chosen on design seeds (bench/mode_sets.py, docs/TUNING.md)
CROSSTALK_QUANTILE = 0.99
#: a leading mode needs this many training rows (flights in alarm) for its limits: fewer say
#: nothing about a high quantile
MIN_ROWS = 50


@dataclass(frozen=True)
class CrossTalk:
    """The design's cross-talk limits: per leading mode, per other mode, the quantile of the
    other mode's pooled own feature on the leading mode's single faults."""

    quantile: float
    limits: Mapping[str, Mapping[str, float]]

    def beyond(self, leader: str, pooled: Mapping[str, float]) -> list[str]:
        """The modes whose pooled own feature in ``pooled`` (mode -> value) exceeds the
        leading mode's cross-talk limit (a missing or NaN value exceeds nothing)."""
        limits = self.limits.get(leader, {})
        return [m for m, t in limits.items()
                if m != leader and not math.isnan(v := pooled.get(m, math.nan)) and v > t]

    def to_dict(self) -> dict[str, Any]:
        return {"quantile": self.quantile,
                "limits": {lead: dict(row) for lead, row in self.limits.items()}}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> CrossTalk:
        q = float(d["quantile"])
        if not 0.0 < q <= 1.0:
            raise ValueError("a cross-talk quantile is in (0, 1]")
        return cls(q, {str(lead): {str(m): float(t) for m, t in row.items()}
                       for lead, row in d["limits"].items()})


def pooled_means(X: np.ndarray, groups: Sequence[Any] | np.ndarray, decay: float) -> np.ndarray:
    """Each row's decayed mean over its group's rows so far, ``s_k / w_k`` with
    ``s_k = decay s_(k-1) + x_k`` and ``w_k = decay w_(k-1) + 1``: the chain's pooling of the
    evidence since an alarm. A group's rows are contiguous and in flight order."""
    X = np.asarray(X, dtype=np.float64)
    g = np.asarray(groups)
    out = np.empty_like(X)
    if not len(g):
        return out
    starts = np.flatnonzero(np.r_[True, g[1:] != g[:-1]])
    for s, e in zip(starts, np.r_[starts[1:], len(g)], strict=True):
        num = lfilter([1.0], [1.0, -decay], np.nan_to_num(X[s:e]), axis=0)
        den = lfilter([1.0], [1.0, -decay], np.ones(e - s))
        out[s:e] = num / den[:, np.newaxis]
    return out


def fit_crosstalk(X: np.ndarray, y: Sequence[Any] | np.ndarray,
                  groups: Sequence[Any] | np.ndarray, *, decay: float,
                  quantile: float = CROSSTALK_QUANTILE,
                  modes: Sequence[str] = PROGRESSIVE) -> CrossTalk:
    """The limits from classifier rows (``X``: one row per flight in alarm of a single fault,
    columns :data:`~server.vocabulary.GENERIC_FEATURES`; ``y`` its mode; ``groups`` its
    pattern), among the progressive ``modes``."""
    pooled = pooled_means(X, groups, decay)
    y = np.asarray(y).astype(str)
    cols = {m: list(GENERIC_FEATURES).index(OWN_FEATURE[m]) for m in modes}
    limits = {lead: {m: float(np.quantile(pooled[y == lead, cols[m]], quantile))
                     for m in modes if m != lead}
              for lead in modes if int((y == lead).sum()) >= MIN_ROWS}
    return CrossTalk(quantile, limits)

