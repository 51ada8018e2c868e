"""Where a fault began to grow: a least-squares change point in a severity history.

A detector alarms some time after a fault's onset (it must first rise clear of the healthy
scatter). The flights in between already carry the growth; a filter started at the alarm throws
them away. :func:`growth_onset` estimates the onset from the inverted measurements of the
actuator's stored history, so that the filter can be replayed from there.

Model (segmented regression, one change point k0)::

    severity_i = 0 + e_i                 for i < k0   (healthy: the self-referenced residual)
    severity_i = a + v (k_i - k0) + e_i  for i >= k0  (the fault's growth, a straight line)

k0 is the candidate that minimises the total squared error (every candidate has the same three
parameters k0, a, v, so the errors compare directly). A straight line suits wear, which grows at
the rate of the sliding distance times the load (Archard); it is not used for the thermal modes,
whose growth accelerates.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from .constants import CONSTANTS

__all__ = ["growth_onset"]

#: the growing part needs at least this many measurements (a line through two is exact)
MIN_GROWTH_POINTS = CONSTANTS.min_growth_points


def growth_onset(index: ArrayLike, severity: ArrayLike) -> int:
    """Flight index k0 at which the growth began (one of ``index``), vectorised over candidates.

    ``index``: flight indices, strictly increasing; ``severity``: inverted measurements there.
    With fewer than ``MIN_GROWTH_POINTS`` measurements the first flight is returned.
    """
    k = np.asarray(index, dtype=float)
    m = np.asarray(severity, dtype=float)
    if k.ndim != 1 or k.shape != m.shape:
        raise ValueError("index and severity must be 1-D of equal length")
    if k.size and (np.any(np.diff(k) <= 0) or not np.all(np.isfinite(m))):
        raise ValueError("index must increase strictly and severity be finite")
    if k.size < MIN_GROWTH_POINTS:
        return int(k[0]) if k.size else 0
    # suffix sums give the least-squares line on every tail k[j:] at once
    x = k - k.mean()  # centred for round-off
    n = np.arange(k.size, 0, -1, dtype=float)
    sx, sy = np.cumsum(x[::-1])[::-1], np.cumsum(m[::-1])[::-1]
    sxx, sxy = np.cumsum((x * x)[::-1])[::-1], np.cumsum((x * m)[::-1])[::-1]
    syy = np.cumsum((m * m)[::-1])[::-1]
    cxx = sxx - sx * sx / n
    cxy = sxy - sx * sy / n
    cyy = syy - sy * sy / n
    line = cyy - np.divide(cxy * cxy, cxx, out=np.zeros_like(cxy), where=cxx > 0)
    flat = np.concatenate([[0.0], np.cumsum(m * m)[:-1]])
    sse = flat + line
    candidates = sse[: k.size - MIN_GROWTH_POINTS + 1]
    return int(k[int(np.argmin(candidates))])
