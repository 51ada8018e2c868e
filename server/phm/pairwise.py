"""NumPy's pairwise summation as compiled functions (numba), so that a compiled loop's sums and
means are the bits NumPy's ``sum``/``mean`` give: eight partial sums over a block of up to 128
values, blocks halved recursively above that (at multiples of eight), the reduction's identity
0.0 added last. Checked against NumPy on lengths 0 to 200,003 in
``tests/phm/test_pairwise.py``.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["PAIRWISE_BLOCK", "PAIRWISE_LANES", "block_sum", "pairwise_sum"]

#: NumPy's pairwise sum: partial sums of a block ...
PAIRWISE_LANES = 8
#: ... of up to this many values (longer spans are halved)
PAIRWISE_BLOCK = 128


@njit(cache=True, inline="always")
def _leaf(a, lo, n):  # type: ignore[no-untyped-def]
    """NumPy's sum of ``a[lo:lo + n]``, n <= 128 (no halving)."""
    if n < PAIRWISE_LANES:
        total = -0.0
        for i in range(lo, lo + n):
            total += a[i]
        return total
    r0, r1, r2, r3 = a[lo], a[lo + 1], a[lo + 2], a[lo + 3]
    r4, r5, r6, r7 = a[lo + 4], a[lo + 5], a[lo + 6], a[lo + 7]
    whole = n - n % PAIRWISE_LANES
    for i in range(lo + PAIRWISE_LANES, lo + whole, PAIRWISE_LANES):
        r0 += a[i]
        r1 += a[i + 1]
        r2 += a[i + 2]
        r3 += a[i + 3]
        r4 += a[i + 4]
        r5 += a[i + 5]
        r6 += a[i + 6]
        r7 += a[i + 7]
    total = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    for i in range(lo + whole, lo + n):
        total += a[i]
    return total


@njit(cache=True, inline="always")
def block_sum(a, lo, n):  # type: ignore[no-untyped-def]
    """Sum of ``a[lo:lo + n]`` (n <= 128) as NumPy adds a row, plus 0.0: a row mean is this
    over n."""
    return 0.0 + _leaf(a, lo, n)


@njit(cache=True)
def pairwise_sum(a):  # type: ignore[no-untyped-def]
    """``np.sum(a)`` of a contiguous 1-d float64 array, to the bit.

    NumPy halves a span above 128 values (the first half a multiple of 8) and adds the two
    halves' sums; the halving is walked here with a stack of pending left sums instead of
    recursion (a recursive compiled function cannot be cached)."""
    n = a.size
    if n <= PAIRWISE_BLOCK:
        return 0.0 + _leaf(a, 0, n)
    depth = 2
    while (PAIRWISE_BLOCK << depth) < n:
        depth += 1
    pending = np.empty(depth + 2)  # left sums waiting for their right halves
    known = np.zeros(depth + 2, dtype=np.bool_)  # whether an open span's left sum is done
    span_lo = np.empty(depth + 2, dtype=np.int64)  # the right half to do after each
    span_n = np.empty(depth + 2, dtype=np.int64)
    top = 0
    lo, m = 0, n
    while True:
        while m > PAIRWISE_BLOCK:  # descend left, remembering each right half
            half = m // 2
            half -= half % PAIRWISE_LANES
            span_lo[top], span_n[top] = lo + half, m - half
            known[top] = False
            top += 1
            m = half
        total = _leaf(a, lo, m)
        while top > 0 and known[top - 1]:  # a right half done: add its left
            top -= 1
            total = pending[top] + total
        if top == 0:
            return 0.0 + total
        pending[top - 1] = total  # the left half of the innermost open span is done
        known[top - 1] = True
        lo, m = span_lo[top - 1], span_n[top - 1]
