"""The building blocks every feature shares: 800 Hz -> 80 Hz block means (bit-exact column
forms of NumPy's row reductions), the exponential filter of the 80 Hz tracks, a feature track
from filtered accumulators (:func:`filtered_track`), least squares from normal-equation
accumulators, and event tracks.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.signal import lfilter

from ..pairwise import PAIRWISE_BLOCK, PAIRWISE_LANES
from .config import FeatureConfig
from .fused import solve_small
from .results import FeatureTrack

__all__ = ["block_mean", "row_means", "row_max", "row_min", "exp_filter", "filter_alpha",
           "filtered_track", "run_length_ok", "normal_accumulators", "solve_normal", "event_track"]


def block_mean(a: np.ndarray, decimation: int) -> np.ndarray:
    """Means of consecutive blocks of ``decimation`` samples along axis 0.

    A trailing partial block is dropped.
    """
    a = np.asarray(a, dtype=np.float64)
    n = a.shape[0] // decimation
    if a.ndim == 1:
        return row_means(a[: n * decimation].reshape(n, decimation))
    return a[: n * decimation].reshape((n, decimation) + a.shape[1:]).mean(axis=1)


def row_means(blocks: np.ndarray) -> np.ndarray:
    """``blocks.mean(axis=1)`` of an (n, d) array, to the bit, in column operations.

    NumPy sums each row with one call of its pairwise sum (rows under 8 elements in turn, else
    8 partial sums combined as a tree, then the remaining elements in turn) added onto 0.0,
    then divides by d. A call per 10-sample row costs more than the additions; the same
    additions in the same order, column by column, cost a third as much.
    """
    d = blocks.shape[1]
    if d == 0 or d > PAIRWISE_BLOCK:
        return blocks.mean(axis=1)
    col = [blocks[:, j] for j in range(d)]
    if d < PAIRWISE_LANES:
        total = col[0].copy()
        for c in col[1:]:
            total += c
    else:
        whole = d - d % PAIRWISE_LANES
        r = col[:PAIRWISE_LANES]
        for i in range(PAIRWISE_LANES, whole, PAIRWISE_LANES):
            r = [r[j] + col[i + j] for j in range(PAIRWISE_LANES)]
        total = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]))
        for c in col[whole:]:
            total += c
    total += 0.0  # onto 0.0: a sum of negative zeros is +0.0, as NumPy's
    total /= d
    return total


def row_max(a: np.ndarray) -> np.ndarray:
    """``a.max(axis=1)`` of a narrow (n, k) array, to the bit, column by column: NumPy's
    reduction over a row keeps the running maximum unless it is NaN or the next value is not
    below it (of two equal values, signed zeros, the later)."""
    acc = a[:, 0]
    for j in range(1, a.shape[1]):
        b = a[:, j]
        acc = np.where((acc > b) | np.isnan(acc), acc, b)
    return acc


def row_min(a: np.ndarray) -> np.ndarray:
    """``a.min(axis=1)`` of a narrow (n, k) array, to the bit (see :func:`row_max`)."""
    acc = a[:, 0]
    for j in range(1, a.shape[1]):
        b = a[:, j]
        acc = np.where((acc < b) | np.isnan(acc), acc, b)
    return acc


def exp_filter(x: np.ndarray, alpha: float) -> np.ndarray:
    """Exponential filter ``y[k] = alpha x[k] + (1 - alpha) y[k-1]`` along axis 0, ``y[-1] = x[0]``.

    Vectorised with :func:`scipy.signal.lfilter`; works on (n,) or (n, m) arrays.
    """
    x = np.asarray(x, dtype=np.float64)
    if x.shape[0] == 0:
        return x.copy()
    zi = ((1.0 - alpha) * x[0])[np.newaxis, ...] if x.ndim > 1 else np.array([(1 - alpha) * x[0]])
    y, _ = lfilter([alpha], [1.0, -(1.0 - alpha)], x, axis=0, zi=zi)
    return y


def filter_alpha(config: FeatureConfig | None = None) -> float:
    """Coefficient of the exponential filter of the 80 Hz tracks, ``1 - exp(-step / tau)``."""
    cfg = config or FeatureConfig()
    return 1.0 - np.exp(-cfg.step_s / cfg.ewma_tau_s)


def filtered_track(acc: np.ndarray, valid: np.ndarray, combine: Callable[[np.ndarray], np.ndarray],
                   alpha: float, min_valid: int = 1) -> FeatureTrack:
    """Filter accumulators ``acc`` (n, m) over valid steps and combine them into a feature."""
    n = acc.shape[0]
    series = np.full(n, np.nan)
    idx = np.flatnonzero(valid)
    if idx.size == 0:
        return FeatureTrack(series, valid, float("nan"), float("nan"), 0)
    acc_valid = acc[idx]
    filt = exp_filter(acc_valid, alpha)
    with np.errstate(divide="ignore", invalid="ignore"):
        f_valid = combine(filt)
        value = float(combine(acc_valid.mean(axis=0, keepdims=True))[0])
    if idx.size < min_valid:
        value = float("nan")
    series[idx] = f_valid
    # hold the last valid value between valid steps
    last = np.maximum.accumulate(np.where(valid, np.arange(n), -1))
    held = last >= 0
    series[held] = series[last[held]]
    finite = f_valid[np.isfinite(f_valid)]
    disp = float(np.std(finite)) if finite.size > 1 else float("nan")
    return FeatureTrack(series, valid, value, disp, int(idx.size))


def _ratio(filt: np.ndarray) -> np.ndarray:
    return filt[:, 0] / filt[:, 1]


def run_length_ok(mask: np.ndarray, min_len: int) -> np.ndarray:
    """Steps of ``mask`` that belong to a run of at least ``min_len`` consecutive True."""
    if min_len <= 1 or mask.size == 0:
        return mask.copy()
    m = mask.astype(np.int8)
    edges = np.diff(np.r_[0, m, 0])
    starts = np.flatnonzero(edges == 1)
    ends = np.flatnonzero(edges == -1)
    lengths = ends - starts
    run_len = np.zeros(mask.size + 1, dtype=np.int64)
    np.add.at(run_len, starts, lengths)
    np.add.at(run_len, ends, -lengths)
    return mask & (np.cumsum(run_len)[:-1] >= min_len)


def normal_accumulators(xs: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Per-step terms of the k x k normal equations of ``y`` on ``xs`` (n, k): the upper
    triangle of ``xs xs'`` (row by row) then the k entries of ``xs y`` (see
    :func:`solve_normal`)."""
    n, k = xs.shape
    iu = np.triu_indices(k)
    out = np.empty((n, iu[0].size + k))
    for c, (i, j) in enumerate(zip(iu[0], iu[1], strict=True)):  # the upper triangle only
        np.multiply(xs[:, i], xs[:, j], out=out[:, c])
    np.multiply(xs, y[:, np.newaxis], out=out[:, iu[0].size:])
    return out


def solve_normal(f: np.ndarray, k: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares coefficients (n, k) from (filtered) normal-equation accumulators, and
    whether each system was well posed (zero coefficients where not)."""
    f = np.ascontiguousarray(f, dtype=np.float64)
    coef, det = solve_small(f, k)
    ok = np.isfinite(det) & (np.abs(det) > 1e-12 * np.abs(f[:, 0]) ** k)
    coef[~ok] = 0.0
    return coef, ok


def event_track(n_steps: int, steps: np.ndarray, vals: np.ndarray, alpha: float,
                absolute: bool = False, min_events: int = 1) -> FeatureTrack:
    acc = np.zeros((n_steps, 2))
    valid = np.zeros(n_steps, dtype=bool)
    v = np.abs(vals) if absolute else vals
    # two events never share a step (runs last at least one step), but be safe
    np.add.at(acc[:, 0], steps, v)
    np.add.at(acc[:, 1], steps, 1.0)
    valid[steps] = True
    return filtered_track(acc, valid, _ratio, alpha, min_events)
