"""The numerics detection is built on: each actuator referred to its own first flights, running
window statistics over a flight sequence, and the offset components learned on healthy flights.

Inputs are the standardised residuals ``z`` of :class:`server.phm.baselines.FleetBaseline`
(dimensionless, N(0, 1) on healthy flights by construction).

Self-reference: production tolerances give every actuator its own offset from the fleet
baseline, larger than its flight-to-flight scatter for some features (docs/TUNING.md,
``reference_flights``). The residual is modelled as ``z = u + e``, an actuator offset
``u ~ N(0, tau^2)`` and flight noise ``e ~ N(0, sigma^2)``; ``tau`` and ``sigma`` are estimated
per feature on healthy sequences (:func:`offset_components`). The first ``reference_flights``
valid residuals of an actuator after installation (or maintenance) form its reference; every
flight is tested against the flights *before* it::

    n = reference flights so far,  n_eff = n (n <= 2) or n / (pi / 2) (median of n),
    u_hat = n_eff tau^2 / (n_eff tau^2 + sigma^2) * median(reference),
    var_u = tau^2 sigma^2 / (n_eff tau^2 + sigma^2),
    z_self = (z - u_hat) / sqrt(sigma^2 + var_u)

(the empirical-Bayes posterior of ``u``; unit variance on healthy flights). With no reference
this is the fleet test, ``z / sqrt(sigma^2 + tau^2)``; the first flight of an actuator is
always judged against the fleet alone.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

__all__ = [
    "MEDIAN_VARIANCE_FACTOR",
    "median_n_eff",
    "offset_components",
    "reference_posterior",
    "running_medians",
    "running_statistics",
    "self_referenced_sequence",
]

#: variance of a sample median over that of the mean (normal samples, large n)
MEDIAN_VARIANCE_FACTOR = math.pi / 2


def median_n_eff(n: np.ndarray | int) -> np.ndarray:
    """Effective sample size of a median of ``n`` values (mean for n <= 2)."""
    n = np.asarray(n, dtype=np.float64)
    return np.where(n > 2, n / MEDIAN_VARIANCE_FACTOR, n)


def running_statistics(z: np.ndarray, window: int, *, median: bool = False) -> np.ndarray:
    """``S_w`` for every flight of a sequence: (n_flights, n_features) -> same shape.

    ``S_w = sqrt(n) mean`` of the last ``n = min(window, available)`` valid residuals, or with
    ``median`` ``sqrt(n / (pi/2)) median`` (unit variance on healthy flights as well, and
    unmoved by a minority of odd flights). NaN residuals (no valid window in that flight) are
    skipped: the window then reaches further back, and a flight without a value holds the
    last statistic. Before any valid residual the statistic is NaN.
    """
    return _running(z, window, "scaled median" if median else "mean")


def running_medians(z: np.ndarray, window: int) -> np.ndarray:
    """The median of the last ``min(window, available)`` valid residuals for every flight of a
    sequence (n_flights, n_features), held through flights without a value; NaN before any."""
    return _running(z, window, "median")


def _running(z: np.ndarray, window: int, statistic: str) -> np.ndarray:
    z = np.asarray(z, dtype=np.float64)
    if z.ndim == 1:
        z = z[:, np.newaxis]
    out = np.full(z.shape, np.nan)
    for j in range(z.shape[1]):
        col = z[:, j]
        ok = np.flatnonzero(np.isfinite(col))
        if ok.size == 0:
            continue
        v = col[ok]
        k = np.arange(1, v.size + 1)
        lo = np.maximum(k - window, 0)
        n = k - lo
        if statistic == "mean":
            cs = np.r_[0.0, np.cumsum(v)]
            s = (cs[k] - cs[lo]) / np.sqrt(n)
        else:
            padded = np.r_[np.full(window - 1, np.nan), v]
            windows = np.lib.stride_tricks.sliding_window_view(padded, window)
            s = np.nanmedian(windows, axis=1)
            if statistic == "scaled median":
                s = s * np.sqrt(median_n_eff(n))
        full = np.full(col.size, np.nan)
        full[ok] = s
        last = np.maximum.accumulate(np.where(np.isfinite(col), np.arange(col.size), -1))
        held = last >= 0
        full[held] = full[last[held]]
        out[:, j] = full
    return out


def reference_posterior(ref: np.ndarray, n: np.ndarray, sigma: np.ndarray,
                        tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Offset estimate ``u_hat`` and the total residual sd ``sqrt(sigma^2 + var_u)`` from the
    median ``ref`` of ``n`` reference residuals (arrays broadcast; ``n == 0`` -> fleet test)."""
    n = np.asarray(n, dtype=np.float64)
    n_eff = median_n_eff(n)
    s2, t2 = sigma**2, tau**2
    denom = n_eff * t2 + s2
    u_hat = np.where(n > 0, n_eff * t2 / denom * np.nan_to_num(ref), 0.0)
    var_u = t2 * s2 / denom
    return u_hat, np.sqrt(s2 + var_u)


def self_referenced_sequence(z: np.ndarray, sigma: np.ndarray, tau: np.ndarray,
                             reference_flights: int,
                             extra_variance: np.ndarray | None = None) -> np.ndarray:
    """Self-referenced residuals of a flight sequence (n_flights, n_features), each flight
    against the median of the first ``reference_flights`` valid residuals *before* it;
    ``extra_variance`` (same shape) adds to each flight's scatter. NaN stays NaN."""
    z = np.asarray(z, dtype=np.float64)
    z = z[:, np.newaxis] if z.ndim == 1 else z
    extra = np.zeros(z.shape) if extra_variance is None else np.asarray(
        extra_variance, dtype=np.float64).reshape(z.shape)
    out = np.full(z.shape, np.nan)
    for j in range(z.shape[1]):
        col = z[:, j]
        ok = np.flatnonzero(np.isfinite(col))
        first = col[ok[:reference_flights]]
        # reference median and count seen by each flight (flights before it only)
        n_before = np.minimum(np.searchsorted(ok, np.arange(col.size)), reference_flights)
        medians = np.array([np.median(first[:k]) if k else 0.0
                            for k in range(min(reference_flights, first.size) + 1)])
        ref = medians[n_before]
        u_hat, sd = reference_posterior(ref, n_before, sigma[j], tau[j])
        out[:, j] = (col - u_hat) / np.sqrt(sd**2 + extra[:, j])
    return out


def offset_components(healthy_sequences: Sequence[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Within-actuator sd ``sigma`` and between-actuator sd ``tau`` of each column, from
    healthy sequences (one per actuator history): robust within scatter (1.4826 MAD of the
    deviations from each sequence's median), ``tau^2`` = variance of the sequence medians less
    their sampling variance (``pi/2 sigma^2 / n``), floored at 0."""
    seqs = [np.asarray(q, dtype=np.float64) for q in healthy_sequences]
    n_feat = seqs[0].shape[1]
    sigma = np.ones(n_feat)
    tau = np.zeros(n_feat)
    for j in range(n_feat):
        cols = [q[:, j][np.isfinite(q[:, j])] for q in seqs]
        cols = [c for c in cols if c.size >= 2]
        if len(cols) < 2:
            continue
        dev = np.concatenate([c - np.median(c) for c in cols])
        n = np.array([c.size for c in cols], dtype=np.float64)
        # the deviations from a sample's own median shrink by about (n - 1) / n
        mad = float(np.median(np.abs(dev))) * 1.4826 * math.sqrt(float(np.mean(n / (n - 1))))
        if not mad > 0:
            continue
        sigma[j] = mad
        medians = np.array([np.median(c) for c in cols])
        t2 = float(np.var(medians, ddof=1)) - MEDIAN_VARIANCE_FACTOR * mad**2 * float(
            np.mean(1.0 / n))
        tau[j] = math.sqrt(max(t2, 0.0))
    return sigma, tau
