"""The 800 Hz -> 80 Hz preparation of one actuator in one compiled pass (numba).

:func:`step_quantities` reads each 800 Hz sample once and writes every step quantity of
:class:`server.phm.features.steps.ActuatorSteps`: the Clarke and Park transforms, the phase
powers and amplitudes per sample, and each step's mean in NumPy's own order of additions
(:func:`block_sum`), so the result is the bits the array form gave (eleven array passes and
fifteen block means before). The trigonometric functions stay in NumPy (its SIMD ``cos`` and
``sin`` need not round as the compiled ones do) and come in as arrays.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["STEP_ROWS", "block_sum", "solve_small", "step_quantities"]

#: rows of :func:`step_quantities`' output, in order
STEP_ROWS = ("speed", "speed_peak", "current", "voltage", "current_sq", "power", "theta",
             "cos_theta", "sin_theta", "x", "i_q", "v_q", "u_a", "u_b", "u_c", "ms_a", "ms_b",
             "ms_c", "common_current")

_LANES = 8  # NumPy's pairwise sum: 8 partial sums over a short row, then the rest in turn


@njit(cache=True, inline="always")
def block_sum(buf, row, d):  # type: ignore[no-untyped-def]  # numba types it from its arguments
    """Sum of ``buf[row, :d]`` (d <= 128) as NumPy's pairwise sum adds it, plus 0.0 (the
    reduction's identity): a row mean is this over d."""
    if d < _LANES:
        total = buf[row, 0]
        for j in range(1, d):
            total += buf[row, j]
    else:
        r0, r1, r2, r3 = buf[row, 0], buf[row, 1], buf[row, 2], buf[row, 3]
        r4, r5, r6, r7 = buf[row, 4], buf[row, 5], buf[row, 6], buf[row, 7]
        whole = d - d % _LANES
        for i in range(_LANES, whole, _LANES):
            r0 += buf[row, i]
            r1 += buf[row, i + 1]
            r2 += buf[row, i + 2]
            r3 += buf[row, i + 3]
            r4 += buf[row, i + 4]
            r5 += buf[row, i + 5]
            r6 += buf[row, i + 6]
            r7 += buf[row, i + 7]
        total = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
        for j in range(whole, d):
            total += buf[row, j]
    return total + 0.0


@njit(cache=True)
def step_quantities(ia, ib, ic, va, vb, vc, theta, x, cos_e, sin_e, cos_m, sin_m,  # type: ignore[no-untyped-def]  # noqa: E501
                    i0_median, sample_rate_hz, n, d):
    """Every step quantity of one actuator, one row per name of :data:`STEP_ROWS` ((19, n)).

    Inputs are 800 Hz float64 arrays of at least ``n * d`` samples: the phase currents and
    voltages, the shaft angle and rod position, ``cos``/``sin`` of the electrical angle
    (``cos_e``, ``sin_e``) and of the shaft angle (``cos_m``, ``sin_m``); ``i0_median`` is the
    flight median of ``ia + ib + ic``. ``speed_peak`` is the step's largest ``|omega|``; every
    other row a step mean.
    """
    out = np.empty((len(STEP_ROWS), n))
    buf = np.empty((len(STEP_ROWS), d))
    root3 = np.sqrt(3.0)
    dt2 = 2.0 * (1.0 / sample_rate_hz)  # np.gradient's central step
    cut = n * d
    for k in range(n):
        peak = -1.0
        for j in range(d):
            s = k * d + j
            a, b, c = ia[s], ib[s], ic[s]
            ua, ub, uc = va[s], vb[s], vc[s]
            i_al = (2.0 * a - b - c) / 3.0
            i_be = (b - c) / root3
            v_al = (2.0 * ua - ub - uc) / 3.0
            v_be = (ub - uc) / root3
            if s == 0:
                w = (theta[1] - theta[0]) / (1.0 / sample_rate_hz)
            elif s == cut - 1:
                w = (theta[s] - theta[s - 1]) / (1.0 / sample_rate_hz)
            else:
                w = (theta[s + 1] - theta[s - 1]) / dt2
            i2 = i_al * i_al + i_be * i_be
            v0 = (ua + ub + uc) / 3.0
            buf[0, j] = w
            if abs(w) > peak or w != w:  # np.maximum: a NaN wins
                peak = abs(w)
            buf[2, j] = np.sqrt(i2)
            buf[3, j] = np.sqrt(v_al * v_al + v_be * v_be)
            buf[4, j] = i2
            buf[5, j] = v_al * i_al + v_be * i_be
            buf[6, j] = theta[s]
            buf[7, j] = cos_m[s]
            buf[8, j] = sin_m[s]
            buf[9, j] = x[s]
            buf[10, j] = -i_al * sin_e[s] + i_be * cos_e[s]
            buf[11, j] = -v_al * sin_e[s] + v_be * cos_e[s]
            buf[12, j] = ua
            buf[13, j] = ub
            buf[14, j] = uc
            buf[15, j] = (ua - v0) * (ua - v0)
            buf[16, j] = (ub - v0) * (ub - v0)
            buf[17, j] = (uc - v0) * (uc - v0)
            buf[18, j] = ((a + b) + c) - i0_median
        for r in range(len(STEP_ROWS)):
            out[r, k] = block_sum(buf, r, d) / d
        out[1, k] = peak
    return out


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
