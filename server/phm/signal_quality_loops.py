"""The per-sample passes of :mod:`server.phm.signal_quality` as compiled loops (numba), one pass
per channel instead of a dozen array passes: integer counts, exact selections, medians by
selection and means in NumPy's order of additions (:mod:`server.phm.pairwise`), so every
figure is the bits the array form gave.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .pairwise import pairwise_sum

__all__ = ["channel_counts", "clipped_mean_square", "hold_flanks", "second_differences",
           "sparse_abs_median"]


@njit(cache=True)
def channel_counts(v, vmax, vmin, stuck_min_len):  # type: ignore[no-untyped-def]  # numba types it from its arguments
    """``(lsb, stuck, saturated)`` of one channel (n >= 2) whose largest and smallest values
    are ``vmax`` and ``vmin`` (NaN if a value is NaN, as ``np.max`` gives): the smallest
    nonzero step between neighbouring samples (NaN if none moved or a step is NaN), the steps
    in runs of zero steps at least ``stuck_min_len`` long, and the samples in runs of at
    least two at either extreme (none if a value is NaN). Runs are counted without
    branches: a run adds its whole length the step it reaches the least, then one a step."""
    n = v.size
    lsb = np.inf
    nan_step = False
    moved = False
    stuck = 0
    run = 0
    for i in range(n - 1):
        step = v[i + 1] - v[i]
        zero = step == 0.0
        nan_step |= step != step
        moved |= not zero
        lsb = min(lsb, np.inf if zero else abs(step))
        run = run + 1 if zero else 0
        stuck += stuck_min_len if run == stuck_min_len else (1 if run > stuck_min_len else 0)
    saturated = 0
    run = 0
    for i in range(n):
        at = v[i] == vmax or v[i] == vmin
        run = run + 1 if at else 0
        saturated += 2 if run == 2 else (1 if run > 2 else 0)
    if nan_step or not moved:
        lsb = np.nan
    return lsb, stuck, saturated


@njit(cache=True)
def second_differences(a, b, c, still):  # type: ignore[no-untyped-def]
    """The second differences ``v[k+2] - 2 v[k+1] + v[k]`` of ``v = a + b + c`` (``b`` and ``c``
    may be None: ``v = a``) over the triples of samples that are all ``still``, in order."""
    n = a.size
    out = np.empty(max(n - 2, 0))
    m = 0
    for k in range(n - 2):
        if still[k] and still[k + 1] and still[k + 2]:
            if b is None or c is None:
                v0, v1, v2 = a[k], a[k + 1], a[k + 2]
            else:
                v0 = (a[k] + b[k]) + c[k]
                v1 = (a[k + 1] + b[k + 1]) + c[k + 1]
                v2 = (a[k + 2] + b[k + 2]) + c[k + 2]
            out[m] = v2 - 2.0 * v1 + v0
            m += 1
    return out[:m]


@njit(cache=True)
def hold_flanks(ia, ib, ic, theta, x, still, radius_m, pole_pairs,  # type: ignore[no-untyped-def]  # noqa: E501
                electrical_offset_rad, min_current_a):
    """The rod position read against the shaft, ``x - r theta``, on the still samples whose
    torque current ``i_q`` (amplitude-invariant Clarke, then Park) exceeds ``min_current_a``
    one way (first array) and the other (second)."""
    n = ia.size
    up = np.empty(n)
    down = np.empty(n)
    n_up = 0
    n_down = 0
    root3 = np.sqrt(3.0)
    for k in range(n):
        if not still[k]:
            continue
        i_al = (2.0 * ia[k] - ib[k] - ic[k]) / 3.0
        i_be = (ib[k] - ic[k]) / root3
        th_e = pole_pairs * theta[k] - electrical_offset_rad
        i_q = -i_al * np.sin(th_e) + i_be * np.cos(th_e)
        rel = x[k] - radius_m * theta[k]
        if i_q > min_current_a:
            up[n_up] = rel
            n_up += 1
        elif i_q < -min_current_a:
            down[n_down] = rel
            n_down += 1
    return up[:n_up], down[:n_down]


@njit(cache=True)
def sparse_abs_median(d2, every):  # type: ignore[no-untyped-def]
    """``np.median(np.abs(d2[::every]))``."""
    return np.median(np.abs(d2[::every]))


@njit(cache=True)
def clipped_mean_square(d2, limit):  # type: ignore[no-untyped-def]
    """``np.mean(c * c)`` of ``c = np.clip(d2, -limit, limit)`` (NaN stays NaN), to the bit."""
    if limit != limit:
        return np.nan
    sq = np.empty(d2.size)
    for i in range(d2.size):
        c = d2[i]
        if c > limit:
            c = limit
        elif c < -limit:
            c = -limit
        sq[i] = c * c
    return pairwise_sum(sq) / d2.size
