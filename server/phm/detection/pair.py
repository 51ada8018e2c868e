"""The winglet pair's rule: a coupled feature's evidence belongs to the drive that has moved
further.

The active drive back-drives its attached standby through the tab, so the standby's screw and
motor drag is part of the hinge work in the active drive's friction ratio: an MTEL-aged partner
raises it by about half its own rise (measured: docs/TUNING.md, ``PAIR_COUPLED_FEATURES``). Of
the pair, a coupled feature's evidence is the drive's that has moved further; the other
drive's is held (it raises no alarm), so an aged drive alarms on itself and its healthy partner
does not. A fault of a drive's own still moves that drive further (its partner sees under half
of it). How far a drive has moved is its level (:func:`pair_level`), not its alarm statistics:
those are clipped, and late in a life both drives' would stand at the clip.

One rule, two forms: :func:`partner_held` for one flight of the online judge
(:mod:`.judge`), :func:`held_sequence` for whole flight sequences (:mod:`.sequences`).
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping, Sequence

import numpy as np

from server.vocabulary import OWN_FEATURE, WINGLET_PAIR

from .config import generic_feature, unit_of
from .statistics import running_medians

__all__ = ["PAIR_COUPLED_FEATURES", "held_sequence", "is_pair_coupled", "level_sequence",
           "pair_level", "partner_held"]

#: generic features a winglet drive's partner moves through the tab
PAIR_COUPLED_FEATURES: tuple[str, ...] = (OWN_FEATURE["MTEL"],)


def is_pair_coupled(name: str) -> bool:
    """Whether the feature ``name`` (``"WL1.F_MTEL"``) is one a partner drive moves too."""
    return generic_feature(name) in PAIR_COUPLED_FEATURES


def pair_level(history: Sequence[float], direction: int) -> float:
    """How far a unit's feature has moved: the median of its last self-referenced residuals
    (unclipped), along the fault's ``direction`` (+1 for a two-sided feature); -inf with
    none."""
    return (direction or 1) * float(np.median(history)) if len(history) else -math.inf


def level_sequence(z_self: np.ndarray, direction: int, window: int) -> np.ndarray:
    """:func:`pair_level` on every flight of one feature's self-referenced residuals
    (n_flights,), over the last ``window`` valid ones up to that flight."""
    level = (direction or 1) * running_medians(z_self, window)[:, 0]
    return np.where(np.isnan(level), -math.inf, level)


def _coupled_pairs() -> Iterator[tuple[str, str, str, str]]:
    """``(unit, partner, unit's feature, partner's feature)`` of every coupled feature."""
    for unit, partner in ((WINGLET_PAIR[0], WINGLET_PAIR[1]), (WINGLET_PAIR[1], WINGLET_PAIR[0])):
        for g in PAIR_COUPLED_FEATURES:
            yield unit, partner, f"{unit}.{g}", f"{partner}.{g}"


def partner_held(levels: Mapping[str, Mapping[str, float]]) -> dict[str, list[str]]:
    """The features of each winglet drive whose evidence belongs to its partner on one flight.

    ``levels``: unit -> feature -> level (:func:`pair_level`) of the units judged together; a
    drive whose partner is not among them holds nothing."""
    held: dict[str, list[str]] = {}
    for unit, partner, mine, theirs in _coupled_pairs():
        if unit not in levels or partner not in levels:
            continue
        if levels[partner].get(theirs, -math.inf) > levels[unit].get(mine, -math.inf):
            held.setdefault(unit, []).append(mine)
    return held


def held_sequence(levels: np.ndarray, feature_names: Sequence[str]) -> np.ndarray:
    """:func:`partner_held` over flight sequences: ``levels`` (n_flights, n_features) of the
    columns ``feature_names`` (-inf with none; columns not pair-coupled are not read) -> True
    where a feature is held. The units judged together are those with a column."""
    col = {n: j for j, n in enumerate(feature_names)}
    units = {unit_of(n) for n in feature_names}
    held = np.zeros(np.shape(levels), dtype=bool)
    for unit, partner, mine, theirs in _coupled_pairs():
        if unit not in units or partner not in units or mine not in col:
            continue
        their_level = levels[:, col[theirs]] if theirs in col else -math.inf
        held[:, col[mine]] = their_level > levels[:, col[mine]]
    return held
