"""A second mode named by its own feature: beyond what the leading mode's fault alone gives it.

A fault moves more than its own feature: a turn-to-turn short raises the motor's current
and with it ``F_DMD``, the dynamic-model deviation. Taught on single faults, the one-vs-rest SVM
learned that a high ``F_TTS`` argues against DMD, so a DMD beside a leading TTS keeps a low own
probability (:mod:`.modes`). Its own feature still tells them apart: on the unit's flights in
alarm, a mode's own feature (pooled since the alarm as the chain pools the class evidence)
above every value the leading mode's faults alone gave it in the design names it present.

Only between modes that share a signal path (:data:`~server.vocabulary.SHARED_SIGNAL_PATH`):
the cross-talk a single-fault design can measure. Beyond them the design's limits do not hold
(a short on one winglet drive beside a partner's magnet fault moves its screw-gap and rod-end
features past every value of the design's shorts), and naming every mode beyond its limit named
a mode the unit does not carry on 12 % of single faults' flights in alarm (docs/TUNING.md).

The limit per leading mode ``L`` and mode ``m`` is a quantile of ``m``'s own feature over the
design's single faults of ``L``, on their flights in alarm (the classifier's training rows,
:func:`server.phm.training.training_rows`), taken flight by flight: a design renders a fault
run every 21st flight, and pooling its flights averages more independent noise than the chain
pools flight by flight, so pooled limits sit too low (docs/TUNING.md). The quantile is chosen on
other design seeds (``bench/mode_sets.py --crosstalk``, docs/TUNING.md ``CROSSTALK``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from server.vocabulary import GENERIC_FEATURES, OWN_FEATURE, SHARED_SIGNAL_PATH

__all__ = ["CrossTalk", "CROSSTALK_QUANTILE", "fit_crosstalk"]

#: the quantile of the design's cross-talk a second mode's pooled own feature must exceed:
#: its highest value, chosen on design seeds (bench/mode_sets.py, docs/TUNING.md)
CROSSTALK_QUANTILE = 1.0
#: a leading mode needs this many training rows (flights in alarm) for its limits: fewer say
#: nothing about a high quantile
MIN_ROWS = 50


@dataclass(frozen=True)
class CrossTalk:
    """The design's cross-talk limits: per leading mode, per mode sharing a signal path with
    it, the quantile of that mode's own feature on the leading mode's single faults' flights
    in alarm."""

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


def fit_crosstalk(X: np.ndarray, y: Sequence[Any] | np.ndarray, *,
                  quantile: float = CROSSTALK_QUANTILE,
                  pairs: Sequence[tuple[str, str]] = SHARED_SIGNAL_PATH) -> CrossTalk:
    """The limits from classifier rows (``X``: one row per flight in alarm of a single fault,
    columns :data:`~server.vocabulary.GENERIC_FEATURES`; ``y`` its mode), for each of the
    ``pairs`` both ways."""
    X = np.asarray(X, dtype=np.float64)
    y = np.asarray(y).astype(str)
    col = {m: list(GENERIC_FEATURES).index(OWN_FEATURE[m]) for pair in pairs for m in pair}
    limits: dict[str, dict[str, float]] = {}
    for lead, m in [*pairs, *((b, a) for a, b in pairs)]:
        values = X[y == lead, col[m]]
        values = values[np.isfinite(values)]
        if values.size >= MIN_ROWS:
            limits.setdefault(lead, {})[m] = float(np.quantile(values, quantile))
    return CrossTalk(quantile, limits)
