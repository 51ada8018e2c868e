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

An alarm raised on a coupled feature alone is an isolation question: either drive's own fault
moves both drives, its own by ``r`` and its partner by ``PAIR_COUPLING r``. The two hypotheses
are weighed on the drives' levels ``(L_1, L_2)`` (:func:`pair_isolation`): under "drive 1"
the levels are ``r (1, k)`` plus the level's noise, under "drive 2" ``r (k, 1)``; with a flat
prior on ``r >= 0`` each hypothesis's evidence is its Gaussian marginal likelihood over ``r``,
and the two probabilities are those likelihoods normalised (equal prior odds). With equal
noise on both levels the log odds are ``(1 - k^2)(L_1^2 - L_2^2) / (2 s^2 (1 + k^2))``: the
drive that moved further leads, as the held rule says, and the margin tells how sure that is.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping, Sequence

import numpy as np

from server.vocabulary import OWN_FEATURE, WINGLET_PAIR

from .config import generic_feature, unit_of
from .statistics import running_medians

__all__ = ["PAIR_COUPLED_FEATURES", "PAIR_COUPLING", "held_sequence", "is_pair_coupled",
           "isolation_of", "level_sequence", "level_sd", "pair_isolation", "pair_level",
           "partner_held"]

#: generic features a winglet drive's partner moves through the tab
PAIR_COUPLED_FEATURES: tuple[str, ...] = (OWN_FEATURE["MTEL"],)
#: the share of a drive's own rise in a coupled feature that its partner's feature shows:
#: 0.44 at half the failure severity, 0.49 at failure (``bench/partner_drag.py``)
PAIR_COUPLING = 0.46


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


def isolation_of(unit: str, features: Sequence[str], levels: Mapping[str, Mapping[str, float]],
                 counts: Mapping[str, Mapping[str, int]]) -> dict[str, float]:
    """The units an alarm of ``unit`` raised on ``features`` names, with the probability of
    each: the unit alone (1.0) unless every feature is coupled and its partner was judged on
    the same flight; then both drives (:func:`pair_isolation` on the coupled feature that
    moved the unit furthest). ``levels`` and ``counts``: unit -> feature -> level, and the
    residuals it rests on."""
    partner = _partner(unit)
    if (partner is None or partner not in levels or not features
            or not all(is_pair_coupled(f) for f in features)):
        return {unit: 1.0}
    mine = max(features, key=lambda f: levels[unit].get(f, -math.inf))
    theirs = f"{partner}.{generic_feature(mine)}"
    p = pair_isolation(levels[unit].get(mine, -math.inf),
                       levels[partner].get(theirs, -math.inf),
                       counts[unit].get(mine, 0), counts[partner].get(theirs, 0))
    return {unit: p, partner: 1.0 - p}


def _partner(unit: str) -> str | None:
    return next((p for p in WINGLET_PAIR if p != unit), None) if unit in WINGLET_PAIR else None


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


def level_sd(n: int) -> float:
    """Standard error of a level (:func:`pair_level`) over ``n`` unit-variance residuals: a
    median's, ``sqrt(pi / 2 / n)``; infinite with none."""
    return math.sqrt(math.pi / 2.0 / n) if n > 0 else math.inf


def _log_evidence(levels: np.ndarray, sds: np.ndarray, shape: np.ndarray) -> float:
    """Log marginal likelihood of ``levels = r shape + noise(sds)`` over a flat prior on r
    (exact for a Gaussian; with levels clipped at zero the fitted ``r`` is never negative, so
    the prior's bound at zero is left out)."""
    w = shape / sds ** 2
    info = float(shape @ w)
    r = float(levels @ w) / info
    rss = float((((levels - r * shape) / sds) ** 2).sum())
    return -0.5 * rss - 0.5 * math.log(info)


def pair_isolation(level: float, partner_level: float, n: int, partner_n: int,
                   coupling: float = PAIR_COUPLING) -> float:
    """Probability that a coupled feature's movement is the drive's own fault, not its
    partner's, from the two drives' levels and how many residuals each rests on.

    A level below zero (against the fault's direction) counts as zero: a fault moves its
    feature one way only. A partner with no level leaves the evidence to the drive (1.0)."""
    if partner_n <= 0 or not math.isfinite(partner_level):
        return 1.0
    if n <= 0 or not math.isfinite(level):
        return 0.0
    levels = np.maximum([level, partner_level], 0.0)
    sds = np.array([level_sd(n), level_sd(partner_n)])
    own = _log_evidence(levels, sds, np.array([1.0, coupling]))
    theirs = _log_evidence(levels, sds, np.array([coupling, 1.0]))
    return float(1.0 / (1.0 + math.exp(min(theirs - own, 700.0))))
