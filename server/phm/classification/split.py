"""Group-aware partitions of the rows: the train/verify split and the calibration folds.

Rows of one degradation pattern (group) are strongly correlated, so no partition here puts a
pattern on both sides; the verification split can also keep every aircraft on one side.
"""

from __future__ import annotations

from collections.abc import Hashable, Sequence
from typing import Any

import numpy as np
from sklearn.model_selection import StratifiedGroupKFold, StratifiedKFold

from .config import CLASSIFIER_DEFAULTS

__all__ = ["split_by_group", "calibration_folds"]


def _union_units(groups: np.ndarray, aircraft: np.ndarray | None) -> np.ndarray:
    """Split unit of each row: the group, or the connected component of groups that share an
    aircraft (so neither a group nor an aircraft can appear on both sides)."""
    _, gi = np.unique(groups, return_inverse=True)
    if aircraft is None:
        return gi
    _, ai = np.unique(aircraft, return_inverse=True)
    n_g = int(gi.max()) + 1
    parent = list(range(n_g + int(ai.max()) + 1))

    def find(a: int) -> int:
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    for g_, a_ in zip(gi.tolist(), ai.tolist(), strict=True):
        ra, rb = find(g_), find(n_g + a_)
        if ra != rb:
            parent[max(ra, rb)] = min(ra, rb)
    roots = np.array([find(g_) for g_ in gi.tolist()])
    return np.unique(roots, return_inverse=True)[1]


def split_by_group(groups: Sequence[Hashable] | np.ndarray, *,
                   y: Sequence[Hashable] | np.ndarray | None = None,
                   aircraft: Sequence[Hashable] | np.ndarray | None = None,
                   test_fraction: float = CLASSIFIER_DEFAULTS.test_fraction,
                   seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Train/test split by degradation pattern; no group on both sides.

    The split unit is the group (pattern id); with ``aircraft`` it is the connected component of
    patterns sharing an aircraft, so no aircraft appears on both sides either. With ``y`` the
    split is stratified: the units of each class (its majority label) are shuffled and
    ``round(test_fraction * n)`` of them, at least 1 and at most ``n - 1``, go to the test side,
    so every class with at least two units has units on both sides (a class with a single
    unit stays in training). Without ``y`` the same rule is applied to all units at once.

    Parameters
    ----------
    groups : array-like of shape (n_samples,)
        Pattern id of each row.
    y : array-like of shape (n_samples,), optional
        Class labels for stratification.
    aircraft : array-like of shape (n_samples,), optional
        Aircraft (tail) of each row.
    test_fraction : float, default 0.3
        Fraction of the units per class held out, in (0, 1).
    seed : int
        Seed of the shuffle (``numpy.random.default_rng``).

    Returns
    -------
    train_idx, test_idx : ndarray of int, sorted
        Row indices of the two sides; together they are ``arange(n_samples)``.
    """
    if not 0.0 < test_fraction < 1.0:
        raise ValueError(f"test_fraction must be in (0, 1), got {test_fraction!r}")
    g = np.asarray(groups)
    if g.ndim != 1:
        raise ValueError("groups must be 1-D")
    n = g.size
    if n == 0:
        return np.zeros(0, dtype=np.intp), np.zeros(0, dtype=np.intp)
    a = None if aircraft is None else np.asarray(aircraft)
    if a is not None and a.shape != g.shape:
        raise ValueError("aircraft must have the same shape as groups")
    unit = _union_units(g, a)
    n_units = int(unit.max()) + 1
    if y is None:
        unit_class = np.zeros(n_units, dtype=np.intp)
    else:
        y_arr = np.asarray(y)
        if y_arr.shape != g.shape:
            raise ValueError("y must have the same shape as groups")
        _, yi = np.unique(y_arr, return_inverse=True)
        counts = np.zeros((n_units, int(yi.max()) + 1), dtype=np.intp)
        np.add.at(counts, (unit, yi), 1)
        unit_class = np.argmax(counts, axis=1)  # majority label (ties: lowest class index)
    rng = np.random.default_rng(seed)
    test_unit = np.zeros(n_units, dtype=bool)
    for c in np.unique(unit_class):
        members = np.flatnonzero(unit_class == c)
        k = members.size
        if k < 2:
            continue
        n_test = min(max(int(round(test_fraction * k)), 1), k - 1)
        test_unit[rng.permutation(members)[:n_test]] = True
    is_test = test_unit[unit]
    return np.flatnonzero(~is_test), np.flatnonzero(is_test)


def calibration_folds(yi: np.ndarray, groups: np.ndarray | None, cv: int,
                       random_state: int | None) -> list[tuple[np.ndarray, np.ndarray]]:
    """Stratified (group) folds; empty when fewer than two folds are possible."""
    shuffle = random_state is not None
    if groups is not None:
        n_splits = min(cv, np.unique(groups).size)
        if n_splits < 2:
            return []
        splitter: Any = StratifiedGroupKFold(n_splits=n_splits, shuffle=shuffle,
                                             random_state=random_state if shuffle else None)
        splits = splitter.split(np.zeros((yi.size, 1)), yi, groups)
    else:
        n_splits = min(cv, int(np.bincount(yi).min()))
        if n_splits < 2:
            return []
        splitter = StratifiedKFold(n_splits=n_splits, shuffle=shuffle,
                                   random_state=random_state if shuffle else None)
        splits = splitter.split(np.zeros((yi.size, 1)), yi)
    return [(tr, te) for tr, te in splits if np.unique(yi[tr]).size >= 2 and te.size]
