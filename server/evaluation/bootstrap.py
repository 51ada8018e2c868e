"""Bootstrap intervals of the evaluation's figures, resampling patterns.

The same resampling matrix for every figure of a given number of patterns (seed fixed), so
that the intervals are reproducible.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from server.phm import metrics

#: bootstrap of the figures over patterns: resamples, central level, seed (reproducible)
N_BOOT = 2000
CI_LEVEL = 0.9
BOOTSTRAP_SEED = 0


def resamples(n: int) -> np.ndarray:
    """The (N_BOOT, n) resampling matrix of ``n`` patterns (the same for every figure)."""
    return metrics.bootstrap_indices(n, n_boot=N_BOOT, seed=BOOTSTRAP_SEED)


def nan_if_none(v: float | None) -> float:
    return math.nan if v is None else float(v)


def finite_max(values: Sequence[float]) -> float | None:
    v = [x for x in values if math.isfinite(x)]
    return float(max(v)) if v else None


def interval(values: Sequence[float] | np.ndarray, idx: np.ndarray, *,
             weights: Sequence[float] | np.ndarray | None = None, scale: float = 1.0
             ) -> list[float] | None:
    """[lo, hi] of the bootstrap interval (times ``scale``), None without values."""
    if len(values) == 0:
        return None
    ci = metrics.bootstrap_mean_interval(values, weights=weights, level=CI_LEVEL,
                                         indices=idx)
    return None if ci is None else [scale * ci[0], scale * ci[1]]


def mean_ci(key: str, values: Sequence[float] | np.ndarray, idx: np.ndarray, *,
            weights: Sequence[float] | np.ndarray | None = None, scale: float = 1.0
            ) -> dict[str, Any]:
    """``{key: mean, key_ci: [lo, hi]}``: the (weighted) mean of the finite values (NaN:
    missing), times ``scale``; None and None without any."""
    v = np.asarray(values, dtype=float)
    w = np.ones_like(v) if weights is None else np.asarray(weights, dtype=float)
    ok = np.isfinite(v) & (w > 0)
    mean = scale * float(np.dot(w[ok], v[ok]) / w[ok].sum()) if ok.any() else None
    return {key: mean, f"{key}_ci": interval(v, idx, weights=weights, scale=scale)}
