"""The per-sample passes of :mod:`server.phm.signal_quality` as compiled loops (numba), one pass
per channel instead of a dozen array passes; integer counts and exact selections, so every
figure is the bits the array form gave. Medians, clipping and means stay in NumPy (its
pairwise sums), on the few arrays these loops select.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["channel_counts", "hold_flanks", "second_differences"]


@njit(cache=True)
def channel_counts(v, stuck_min_len):  # type: ignore[no-untyped-def]  # numba types it from its arguments
    """``(lsb, stuck, saturated)`` of one channel (n >= 2): the smallest nonzero step between
    neighbouring samples (NaN if none moved, or if a step is NaN), the samples of the step
    series in runs of zero steps at least ``stuck_min_len`` long, and the samples in runs of at
    least two at the channel's largest or smallest value (none if a value is NaN)."""
    n = v.size
    vmax = v[0]
    vmin = v[0]
    has_nan = v[0] != v[0]
    for i in range(1, n):
        x = v[i]
        if x != x:
            has_nan = True
        elif x > vmax:
            vmax = x
        elif x < vmin:
            vmin = x
    lsb = np.inf
    moved = False
    nan_step = has_nan
    stuck = 0
    run = 0
    for i in range(n - 1):
        step = v[i + 1] - v[i]
        if step == 0.0:
            run += 1
            continue
        if run >= stuck_min_len:
            stuck += run
        run = 0
        moved = True
        if step != step:  # inf - inf
            nan_step = True
        elif abs(step) < lsb:
            lsb = abs(step)
    if run >= stuck_min_len:
        stuck += run
    saturated = 0
    if not has_nan:
        run = 0
        for i in range(n):
            if v[i] == vmax or v[i] == vmin:
                run += 1
                continue
            if run >= 2:
                saturated += run
            run = 0
        if run >= 2:
            saturated += run
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
