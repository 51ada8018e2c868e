"""The features' compiled loops (numba): the 800 Hz -> 80 Hz preparation of one actuator in
one pass (:func:`step_quantities`) and the small least-squares systems (:func:`solve_small`).

:func:`step_quantities` reads each 800 Hz sample once and writes every step quantity of
:class:`server.phm.features.steps.ActuatorSteps`: the Clarke and Park transforms, the phase
powers and amplitudes per sample, and each step's mean in NumPy's own order of additions
(:func:`server.phm.pairwise.block_sum`), so the result is the bits the array form gave
(eleven array passes and fifteen block means before). NumPy's float64 ``cos`` and ``sin``
are glibc's, as the compiled ones are (equal on every one of 10 million angles up to
1e5 rad); a NumPy that brought its own would show in
``tests/phm/test_feature_regression.py``.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..pairwise import block_sum

__all__ = ["STEP_ROWS", "solve_small", "step_quantities"]

#: rows of :func:`step_quantities`' output, in order
STEP_ROWS = ("speed", "speed_peak", "current", "voltage", "current_sq", "power", "theta",
             "cos_theta", "sin_theta", "x", "i_q", "v_q", "u_a", "u_b", "u_c", "ms_a", "ms_b",
             "ms_c", "common_current")

_N_ROWS = len(STEP_ROWS)
_CHUNK = 64  # steps transformed before they are summed: their samples stay in cache


@njit(cache=True)
def step_quantities(ia, ib, ic, va, vb, vc, theta, x, i0_median, pole_pairs,  # type: ignore[no-untyped-def]  # noqa: E501
                    electrical_offset_rad, sample_rate_hz, n, d):
    """Every step quantity of one actuator, one row per name of :data:`STEP_ROWS` ((19, n)).

    Inputs are 800 Hz float64 arrays of at least ``n * d`` samples: the phase currents and
    voltages, the shaft angle and rod position; ``i0_median`` is the flight median of
    ``ia + ib + ic``; the electrical angle is ``pole_pairs theta - electrical_offset_rad``.
    ``speed_peak`` is the step's largest ``|omega|`` (``np.gradient`` of ``theta``); every
    other row a step mean. Steps go in chunks whose samples are transformed in loops of their
    own (the trigonometric calls apart, glibc's as NumPy's), then summed step by step.
    """
    out = np.empty((_N_ROWS, n))
    buf = np.empty((_N_ROWS, _CHUNK * d))
    root3 = np.sqrt(3.0)
    h = 1.0 / sample_rate_hz
    cut = n * d
    for k0 in range(0, n, _CHUNK):
        s0 = k0 * d
        ns = (min(n, k0 + _CHUNK) - k0) * d
        for j in range(ns):
            th = theta[s0 + j]
            th_e = pole_pairs * th - electrical_offset_rad
            buf[7, j] = np.cos(th)
            buf[8, j] = np.sin(th)
            buf[10, j] = np.cos(th_e)  # overwritten below by i_q and v_q
            buf[11, j] = np.sin(th_e)
        for j in range(ns):
            s = s0 + j
            a, b, c = ia[s], ib[s], ic[s]
            ua, ub, uc = va[s], vb[s], vc[s]
            i_al = (2.0 * a - b - c) / 3.0
            i_be = (b - c) / root3
            v_al = (2.0 * ua - ub - uc) / 3.0
            v_be = (ub - uc) / root3
            i2 = i_al * i_al + i_be * i_be
            v0 = (ua + ub + uc) / 3.0
            ce, se = buf[10, j], buf[11, j]
            buf[2, j] = np.sqrt(i2)
            buf[3, j] = np.sqrt(v_al * v_al + v_be * v_be)
            buf[4, j] = i2
            buf[5, j] = v_al * i_al + v_be * i_be
            buf[6, j] = theta[s]
            buf[9, j] = x[s]
            buf[10, j] = -i_al * se + i_be * ce
            buf[11, j] = -v_al * se + v_be * ce
            buf[12, j] = ua
            buf[13, j] = ub
            buf[14, j] = uc
            buf[15, j] = (ua - v0) * (ua - v0)
            buf[16, j] = (ub - v0) * (ub - v0)
            buf[17, j] = (uc - v0) * (uc - v0)
            buf[18, j] = ((a + b) + c) - i0_median
        _speed(theta, s0, ns, cut, h, buf)
        for kk in range(ns // d):
            peak = -1.0
            for j in range(kk * d, kk * d + d):
                w = buf[0, j]
                if abs(w) > peak or w != w:  # np.maximum: a NaN wins
                    peak = abs(w)
            out[1, k0 + kk] = peak
            for r in range(_N_ROWS):
                if r != 1:
                    out[r, k0 + kk] = block_sum(buf[r], kk * d, d) / d
    return out


@njit(cache=True, inline="always")
def _speed(theta, s0, ns, cut, h, buf):  # type: ignore[no-untyped-def]
    """``np.gradient(theta[:cut], h)`` over samples ``s0 .. s0 + ns`` into ``buf[0]``: central
    differences, one-sided at the ends."""
    lo = 1 if s0 == 0 else 0
    hi = ns - 1 if s0 + ns == cut else ns
    dt2 = 2.0 * h
    for j in range(lo, hi):
        buf[0, j] = (theta[s0 + j + 1] - theta[s0 + j - 1]) / dt2
    if lo == 1:
        buf[0, 0] = (theta[1] - theta[0]) / h
    if hi == ns - 1:
        buf[0, ns - 1] = (theta[cut - 1] - theta[cut - 2]) / h


@njit(cache=True)
def solve_small(f, k):  # type: ignore[no-untyped-def]  # numba types it from its arguments
    """Per row of ``f`` (n, k (k + 1) / 2 + k): the k x k symmetric normal equations (the upper
    triangle row by row, then the right-hand side) solved by Gaussian elimination with
    partial pivoting, their determinant from the same factors; (n, k) coefficients and (n,)
    determinants. The same arithmetic on every machine: LAPACK's kernels (and so the last bits
    of its answers) depend on the processor."""
    n = f.shape[0]
    m = k * (k + 1) // 2
    coef = np.zeros((n, k))
    det = np.empty(n)
    a = np.empty((k, k))
    b = np.empty(k)
    for r in range(n):
        c = 0
        for i in range(k):
            for j in range(i, k):
                a[i, j] = f[r, c]
                a[j, i] = f[r, c]
                c += 1
            b[i] = f[r, m + i]
        sign = 1.0
        for col in range(k):
            piv = col
            for i in range(col + 1, k):
                if abs(a[i, col]) > abs(a[piv, col]):
                    piv = i
            if piv != col:
                sign = -sign
                for j in range(k):
                    a[col, j], a[piv, j] = a[piv, j], a[col, j]
                b[col], b[piv] = b[piv], b[col]
            if a[col, col] != 0.0:
                for i in range(col + 1, k):
                    factor = a[i, col] / a[col, col]
                    for j in range(col + 1, k):
                        a[i, j] -= factor * a[col, j]
                    b[i] -= factor * b[col]
        d = sign
        for i in range(k):
            d *= a[i, i]
        det[r] = d
        if d != 0.0 and d == d:
            for i in range(k - 1, -1, -1):
                s = b[i]
                for j in range(i + 1, k):
                    s -= a[i, j] * coef[r, j]
                coef[r, i] = s / a[i, i]
    return coef, det
