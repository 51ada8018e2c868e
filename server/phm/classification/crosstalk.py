"""A second mode named by its own feature: beyond what the leading mode's fault alone gives it.

A fault moves more than its own feature: a turn-to-turn short raises the motor's current
and with it ``F_DMD``, the dynamic-model deviation. Taught on single faults, the one-vs-rest SVM
learned that a high ``F_TTS`` argues against DMD, so a DMD beside a leading TTS keeps a low own
probability (:mod:`.modes`). Its own feature still tells them apart: on the unit's flights in
alarm, a mode's own feature (pooled since the alarm as the chain pools the class evidence)
above what the leading mode's faults alone gave it in the design names it present.

The cross-talk grows with the leading fault: a mild short lifts ``F_DMD`` a little, a severe
one a lot. So the limit follows the leading mode's own feature ``x`` (pooled likewise):
``at + slope * x``, the slope the least-squares line of the mode's feature on ``x`` over the
leading mode's single faults (clipped at 0), ``at`` the quantile of what lies above it, and
never below what the milder half of those faults gave (there the healthy scatter sets the
feature, not the cross-talk). A second mode is then named beside a mild leader once it is out
of that scatter, where one limit for every severity waits until it exceeds what the strongest
leader gave (docs/TUNING.md, ``CROSSTALK``).

Only between modes that share a signal path (:data:`~server.vocabulary.SHARED_SIGNAL_PATH`):
the cross-talk a single-fault design can measure. Beyond them the design's limits do not hold
(a short on one winglet drive beside a partner's magnet fault moves its screw-gap and rod-end
features past every value of the design's shorts), and naming every mode beyond its limit named
a mode the unit does not carry on 12 % of single faults' flights in alarm (docs/TUNING.md).

The limits are fitted on the leading mode's single faults in the design, their flights in
alarm (the classifier's training rows, :func:`server.phm.training.training_rows`), flight by
flight: a design renders a fault run every 21st flight, and pooling its flights averages more
independent noise than the chain pools flight by flight, so pooled limits sit too low
(docs/TUNING.md); a line fitted on single flights holds for their pooled means. The quantile is
chosen on other design seeds (``bench/mode_sets.py --crosstalk``, docs/TUNING.md
``CROSSTALK``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from server.vocabulary import GENERIC_FEATURES, OWN_FEATURE, SHARED_SIGNAL_PATH

__all__ = ["CrossTalk", "CrossTalkLimit", "CROSSTALK_QUANTILE", "fit_crosstalk"]

#: the quantile of the design's cross-talk a second mode's pooled own feature must exceed:
#: its highest value, chosen on design seeds (bench/mode_sets.py, docs/TUNING.md)
CROSSTALK_QUANTILE = 1.0
#: a leading mode needs this many training rows (flights in alarm) for its limits: fewer say
#: nothing about a high quantile
MIN_ROWS = 50
#: the limit does not fall below what the leader's flights up to this quantile of its own
#: feature gave (the milder half: docs/TUNING.md, ``CROSSTALK``)
MILDER = 0.5


@dataclass(frozen=True)
class CrossTalkLimit:
    """A mode's limit beside a leading mode whose own feature is ``x``: ``at + slope * x``,
    not below ``floor`` (``slope`` 0: ``at`` whatever the leader's severity)."""

    at: float
    slope: float = 0.0
    floor: float = -math.inf

    def of(self, lead_value: float) -> float:
        """The limit at the leading mode's own feature ``lead_value`` (NaN where the limit
        follows the leader and its feature is unknown: nothing is beyond it)."""
        if self.slope == 0.0:
            return self.at
        if math.isnan(lead_value):
            return math.nan
        return max(self.at + self.slope * lead_value, self.floor)

    def to_dict(self) -> dict[str, float]:
        return {"at": self.at, "slope": self.slope,
                **({} if self.floor == -math.inf else {"floor": self.floor})}

    @classmethod
    def from_dict(cls, d: float | Mapping[str, Any]) -> CrossTalkLimit:
        """A limit, or a number (a document of the flat limits: that limit at every
        severity)."""
        if isinstance(d, Mapping):
            at, slope = float(d["at"]), float(d.get("slope", 0.0))
            floor = float(d.get("floor", -math.inf))
        else:
            at, slope, floor = float(d), 0.0, -math.inf
        if not (math.isfinite(at) and math.isfinite(slope)) or slope < 0.0 or math.isnan(floor):
            raise ValueError("a cross-talk limit is finite and its slope non-negative")
        return cls(at, slope, floor)


@dataclass(frozen=True)
class CrossTalk:
    """The design's cross-talk limits: per leading mode, per mode sharing a signal path with
    it, the limit on that mode's own feature given the leading mode's own feature."""

    quantile: float
    limits: Mapping[str, Mapping[str, CrossTalkLimit]]

    def beyond(self, leader: str, pooled: Mapping[str, float]) -> list[str]:
        """The modes whose pooled own feature in ``pooled`` (mode -> value) exceeds the
        leading mode's cross-talk limit at the leader's pooled own feature (a missing or NaN
        value exceeds nothing)."""
        limits = self.limits.get(leader, {})
        x = pooled.get(leader, math.nan)
        return [m for m, limit in limits.items()
                if m != leader and not math.isnan(v := pooled.get(m, math.nan))
                and v > limit.of(x)]

    def to_dict(self) -> dict[str, Any]:
        return {"quantile": self.quantile,
                "limits": {lead: {m: lim.to_dict() for m, lim in row.items()}
                           for lead, row in self.limits.items()}}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> CrossTalk:
        q = float(d["quantile"])
        if not 0.0 < q <= 1.0:
            raise ValueError("a cross-talk quantile is in (0, 1]")
        return cls(q, {str(lead): {str(m): CrossTalkLimit.from_dict(t) for m, t in row.items()}
                       for lead, row in d["limits"].items()})


def _limit(lead: np.ndarray, values: np.ndarray, quantile: float, milder: float | None,
           follow: bool) -> CrossTalkLimit:
    """The ``quantile`` of ``values`` above their least-squares line on ``lead`` (slope
    clipped at 0: cross-talk adds to a feature, and a falling limit extrapolated past the
    design's strongest faults would name a mode on every stronger one), not below the
    ``quantile`` of ``values`` on the milder half of the leader's flights (where the healthy
    scatter, not the cross-talk, sets the feature and the line extrapolated below them
    would name a mode on a mild leader's noise); without ``follow``, the quantile itself."""
    slope = (max(float(np.polyfit(lead, values, 1)[0]), 0.0)
             if follow and np.ptp(lead) > 0.0 else 0.0)
    if slope == 0.0:
        return CrossTalkLimit(float(np.quantile(values, quantile)))
    floor = (-math.inf if milder is None
             else float(np.quantile(values[lead <= np.quantile(lead, milder)], quantile)))
    return CrossTalkLimit(float(np.quantile(values - slope * lead, quantile)), slope, floor)


def fit_crosstalk(X: np.ndarray, y: Sequence[Any] | np.ndarray, *,
                  quantile: float = CROSSTALK_QUANTILE,
                  pairs: Sequence[tuple[str, str]] = SHARED_SIGNAL_PATH,
                  conditional: bool = True, milder: float | None = MILDER) -> CrossTalk:
    """The limits from classifier rows (``X``: one row per flight in alarm of a single fault,
    columns :data:`~server.vocabulary.GENERIC_FEATURES`; ``y`` its mode), for each of the
    ``pairs`` both ways; ``conditional``: each following the leading mode's own feature, not
    below the quantile of the leader's flights up to its ``milder`` quantile (None: no floor);
    else one limit per pair, the quantile itself."""
    X = np.asarray(X, dtype=np.float64)
    y = np.asarray(y).astype(str)
    col = {m: list(GENERIC_FEATURES).index(OWN_FEATURE[m]) for pair in pairs for m in pair}
    limits: dict[str, dict[str, CrossTalkLimit]] = {}
    for lead, m in [*pairs, *((b, a) for a, b in pairs)]:
        x, v = X[y == lead, col[lead]], X[y == lead, col[m]]
        keep = np.isfinite(v) & (np.isfinite(x) if conditional else True)
        if keep.sum() >= MIN_ROWS:
            limits.setdefault(lead, {})[m] = _limit(x[keep], v[keep], quantile, milder,
                                                    conditional)
    return CrossTalk(quantile, limits)
