"""Prognostic and detection performance metrics, as plain functions over arrays.

Prognostic metrics after A. Saxena, J. Celaya, E. Balaban, K. Goebel, B. Saha, S. Saha,
M. Schwabacher, "Metrics for evaluating performance of prognostic techniques", Proc. Int. Conf. on
Prognostics and Health Management (PHM 2008), Denver, 2008, pp. 1-17 (the paper's reference [48]);
formulas as refined in Saxena et al., "Metrics for offline evaluation of prognostic performance",
IJPHM 1(1), 2010.

Conventions
-----------
- ``times`` t_i are the prediction times (flights, or any time unit used consistently), increasing.
- ``t_eol`` is the true end of life (failure time) in the same unit; the true RUL at t_i is
  r*(t_i) = t_eol - t_i.
- ``rul_pred`` r(t_i) is a point estimate per prediction (the paper uses the most probable RUL; we
  use the median).
- ``t_p`` is the time of the first prediction (after fault detection).
- Times at or after ``t_eol`` (true RUL <= 0) are excluded from the relative measures.
"""

from __future__ import annotations

import math
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.stats import binomtest

__all__ = [
    "proportion_interval",
    "alpha_bounds_hit",
    "alpha_lambda",
    "alpha_lambda_probability",
    "bootstrap_indices",
    "bootstrap_mean_interval",
    "convergence",
    "cumulative_relative_accuracy",
    "detection_time",
    "event_rate",
    "false_alarm_rate",
    "interval_coverage",
    "interval_hits",
    "mean_relative_accuracy",
    "missed_detection_rate",
    "prognostic_horizon",
    "prognostic_horizon_nondimensional",
    "relative_accuracy",
]


def _arrays(
    times: ArrayLike, rul_pred: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    t = np.asarray(times, dtype=float).ravel()
    r = np.asarray(rul_pred, dtype=float).ravel()
    if t.shape != r.shape:
        raise ValueError("times and rul_pred must have the same length")
    if t.size and np.any(np.diff(t) <= 0):
        raise ValueError("times must be strictly increasing")
    return t, r


def relative_accuracy(rul_pred: ArrayLike, rul_true: ArrayLike) -> NDArray[np.float64]:
    """Relative accuracy RA = 1 - |r* - r| / r*, element-wise (Saxena 2008, eq. for RA_lambda).

    1 is perfect; it is negative when the error exceeds the true RUL. r* must be > 0.
    """
    r = np.asarray(rul_pred, dtype=float)
    rs = np.asarray(rul_true, dtype=float)
    if np.any(rs <= 0):
        raise ValueError("true RUL must be > 0 for relative accuracy")
    return 1.0 - np.abs(rs - r) / rs


def mean_relative_accuracy(rul_pred: ArrayLike, rul_true: ArrayLike) -> float:
    """Mean of RA over the predictions (the paper's Table 2 "relative accuracy")."""
    return float(np.mean(relative_accuracy(rul_pred, rul_true)))


def cumulative_relative_accuracy(
    rul_pred: ArrayLike, rul_true: ArrayLike, weights: ArrayLike | None = None
) -> float:
    """CRA = sum_i w_i RA_i / sum_i w_i over the predictions (Saxena 2008).

    ``weights`` default to uniform (then CRA equals the mean RA); Saxena suggests weights that
    grow toward end of life, where accuracy matters most.
    """
    ra = relative_accuracy(rul_pred, rul_true)
    w = np.ones_like(ra) if weights is None else np.asarray(weights, dtype=float)
    if w.shape != ra.shape or np.any(w < 0) or w.sum() <= 0:
        raise ValueError("weights must be non-negative, one per prediction, not all zero")
    return float(np.dot(w, ra) / w.sum())


def alpha_bounds_hit(
    rul_pred: ArrayLike,
    rul_true: ArrayLike,
    *,
    alpha: float = 0.2,
    t_eol: float | None = None,
    bounds: Literal["relative", "eol"] = "relative",
) -> NDArray[np.bool_]:
    """Whether each prediction lies within the alpha bounds around the true RUL.

    ``"relative"``: (1 - alpha) r* <= r <= (1 + alpha) r* (the alpha-lambda cone, the paper's
    +-20 % cone). ``"eol"``: r* - alpha t_eol <= r <= r* + alpha t_eol (Saxena's constant-width
    bounds for the prognostic horizon; needs ``t_eol``, or the life length measured from
    prediction time zero).
    """
    r = np.asarray(rul_pred, dtype=float)
    rs = np.asarray(rul_true, dtype=float)
    if not (0 < alpha < 1):
        raise ValueError("alpha must be in (0, 1)")
    if bounds == "relative":
        return (r >= (1 - alpha) * rs) & (r <= (1 + alpha) * rs)
    if bounds == "eol":
        if t_eol is None:
            raise ValueError("bounds='eol' needs t_eol")
        return np.abs(r - rs) <= alpha * t_eol
    raise ValueError(f"unknown bounds {bounds!r}")


def prognostic_horizon(
    times: ArrayLike,
    rul_pred: ArrayLike,
    t_eol: float,
    *,
    alpha: float = 0.2,
    bounds: Literal["relative", "eol"] = "relative",
    stay: bool = True,
) -> float:
    """Prognostic horizon PH = t_eol - t_i (Saxena 2008).

    i is the first prediction inside the alpha bounds (see :func:`alpha_bounds_hit`); with
    ``stay=True`` (the paper's definition: "falls, and remains") i is the first prediction from
    which *all* later predictions before t_eol stay inside. Returns 0.0 when no prediction
    qualifies. With ``bounds="eol"`` the band width is alpha * t_eol, measured from time 0.
    """
    t, r = _arrays(times, rul_pred)
    keep = t < t_eol
    t, r = t[keep], r[keep]
    if t.size == 0:
        return 0.0
    hit = alpha_bounds_hit(r, t_eol - t, alpha=alpha, t_eol=t_eol, bounds=bounds)
    if stay:
        # suffix "all": ok[i] is True when hit[i:] are all True
        ok = np.flip(np.logical_and.accumulate(np.flip(hit)))
    else:
        ok = hit
    idx = np.flatnonzero(ok)
    return float(t_eol - t[idx[0]]) if idx.size else 0.0


def prognostic_horizon_nondimensional(
    times: ArrayLike,
    rul_pred: ArrayLike,
    t_eol: float,
    *,
    t_start: float | None = None,
    alpha: float = 0.2,
    bounds: Literal["relative", "eol"] = "relative",
    stay: bool = True,
) -> float:
    """PH / (t_eol - t_start), in [0, 1] (the paper's Table 2 "prognostic horizon [-]").

    ``t_start`` is the start of the life considered (default: the first prediction time t_p,
    i.e. the fault detection; pass the fault onset to normalise over the whole faulty life).
    """
    t, _ = _arrays(times, rul_pred)
    start = float(t[0]) if t_start is None else float(t_start)
    life = t_eol - start
    if life <= 0:
        raise ValueError("t_eol must be after t_start")
    return prognostic_horizon(times, rul_pred, t_eol, alpha=alpha, bounds=bounds, stay=stay) / life


def alpha_lambda(
    times: ArrayLike,
    rul_pred: ArrayLike,
    t_eol: float,
    *,
    alpha: float = 0.2,
    lam: float = 0.5,
    t_p: float | None = None,
) -> bool:
    """alpha-lambda accuracy (Saxena 2008): is r(t_lambda) within (1 +- alpha) r*(t_lambda)?

    t_lambda = t_p + lam (t_eol - t_p); the prediction used is the last one made at or before
    t_lambda (predictions are only available at discrete times). ``t_p`` defaults to the first
    prediction time.
    """
    t, r = _arrays(times, rul_pred)
    if not (0 <= lam <= 1):
        raise ValueError("lam must be in [0, 1]")
    tp = float(t[0]) if t_p is None else float(t_p)
    t_lam = tp + lam * (t_eol - tp)
    idx = np.searchsorted(t, t_lam, side="right") - 1
    if idx < 0 or t[idx] >= t_eol:
        return False
    return bool(alpha_bounds_hit(r[idx], t_eol - t[idx], alpha=alpha))


def alpha_lambda_probability(
    rul_samples: ArrayLike,
    rul_true: float,
    *,
    weights: ArrayLike | None = None,
    alpha: float = 0.2,
    beta: float = 0.5,
) -> bool:
    """Distribution form of alpha-lambda: probability mass within (1 +- alpha) r* is >= beta."""
    s = np.asarray(rul_samples, dtype=float).ravel()
    w = np.full(s.size, 1.0 / s.size) if weights is None else np.asarray(weights, dtype=float)
    inside = (s >= (1 - alpha) * rul_true) & (s <= (1 + alpha) * rul_true)
    return bool(w[inside].sum() / w.sum() >= beta)


def convergence(times: ArrayLike, error: ArrayLike, *, t_p: float | None = None) -> float:
    """Convergence C_M: distance from (t_p, 0) to the centroid of the area under M(t) (Saxena 2008).

    With M_i the error metric at t_i (e.g. |relative error|) and the last interval dropped::

        x_c = 1/2 sum_i (t_{i+1}^2 - t_i^2) M_i / sum_i (t_{i+1} - t_i) M_i
        y_c = 1/2 sum_i (t_{i+1} - t_i) M_i^2  / sum_i (t_{i+1} - t_i) M_i
        C_M = sqrt((x_c - t_p)^2 + y_c^2)

    Lower is better (the error shrinks early). Needs at least two predictions and some error;
    returns 0.0 when the error is identically zero.
    """
    t, m = _arrays(times, error)
    if t.size < 2:
        raise ValueError("convergence needs at least two predictions")
    tp = float(t[0]) if t_p is None else float(t_p)
    dt = np.diff(t)
    mi = m[:-1]
    area = float(np.dot(dt, mi))
    if area == 0.0:
        return 0.0
    x_c = 0.5 * float(np.dot(t[1:] ** 2 - t[:-1] ** 2, mi)) / area
    y_c = 0.5 * float(np.dot(dt, mi**2)) / area
    return math.hypot(x_c - tp, y_c)


def false_alarm_rate(alarm_raised: ArrayLike, is_faulty: ArrayLike) -> float:
    """FP / (FP + TN): share of healthy cases (or samples) with an alarm. nan if no healthy case."""
    a = np.asarray(alarm_raised, dtype=bool)
    f = np.asarray(is_faulty, dtype=bool)
    healthy = ~f
    n = int(healthy.sum())
    return float((a & healthy).sum() / n) if n else math.nan


def event_rate(events: int, trials: int, level: float = 0.90) -> dict[str, Any]:
    """False alarms (or any events) per unit-flight with the rate's exact (Clopper-Pearson)
    ``level`` interval: ``{"events", "unit_flights", "rate", "interval"}``, rate and interval
    None without a unit-flight."""
    if trials <= 0:
        return {"events": events, "unit_flights": 0, "rate": None, "interval": None}
    return {"events": events, "unit_flights": trials, "rate": events / trials,
            "interval": proportion_interval(events, trials, level)}


def proportion_interval(hits: int, trials: int, level: float = 0.90) -> list[float]:
    """The exact (Clopper-Pearson) ``level`` interval ``[lo, hi]`` of a share ``hits /
    trials`` (``trials`` > 0): a rate per unit-flight, a share of alarms named right."""
    ci = binomtest(hits, trials).proportion_ci(level, method="exact")
    return [float(ci.low), float(ci.high)]


def missed_detection_rate(alarm_raised: ArrayLike, is_faulty: ArrayLike) -> float:
    """FN / (FN + TP): share of faulty cases (or samples) without an alarm. nan if none faulty."""
    a = np.asarray(alarm_raised, dtype=bool)
    f = np.asarray(is_faulty, dtype=bool)
    n = int(f.sum())
    return float((~a & f).sum() / n) if n else math.nan


def detection_time(times: ArrayLike, alarm: ArrayLike, onset_time: float) -> float:
    """Delay from fault onset to the first alarm at or after the onset (same unit as ``times``).

    Returns nan when there is no alarm at or after the onset (a missed detection); alarms before
    the onset are false alarms and are ignored here.
    """
    t = np.asarray(times, dtype=float).ravel()
    a = np.asarray(alarm, dtype=bool).ravel()
    if t.shape != a.shape:
        raise ValueError("times and alarm must have the same length")
    idx = np.flatnonzero(a & (t >= onset_time))
    return float(t[idx[0]] - onset_time) if idx.size else math.nan


# ----------------------------------------------------------------------------------------------
# uncertainty of the figures: interval coverage, bootstrap over clusters


def interval_hits(value: ArrayLike, lower: ArrayLike, upper: ArrayLike) -> NDArray[np.bool_]:
    """Whether each ``value`` lies in its closed interval [lower, upper], element-wise.

    A NaN bound (no interval) is a miss; an infinite bound is open on that side.
    """
    v = np.asarray(value, dtype=float)
    lo = np.asarray(lower, dtype=float)
    hi = np.asarray(upper, dtype=float)
    with np.errstate(invalid="ignore"):
        return (v >= lo) & (v <= hi)


def interval_coverage(value: ArrayLike, lower: ArrayLike, upper: ArrayLike) -> float:
    """Share of the values inside their intervals (:func:`interval_hits`); nan when empty.

    With the central ``p`` interval of a calibrated predictive distribution (e.g. its 25 and
    75 % quantiles for p = 0.5) the coverage tends to ``p``.
    """
    hits = interval_hits(value, lower, upper)
    return float(hits.mean()) if hits.size else math.nan


def bootstrap_indices(n_clusters: int, *, n_boot: int = 2000, seed: int = 0) -> NDArray[np.intp]:
    """(n_boot, n_clusters) cluster indices drawn with replacement (one resample per row).

    Draw it once and pass it to every :func:`bootstrap_mean_interval` of the same clusters, so
    the intervals of several figures come from the same resamples.
    """
    if n_clusters < 0 or n_boot < 1:
        raise ValueError("n_clusters must be >= 0 and n_boot >= 1")
    rng = np.random.default_rng(seed)
    return rng.integers(0, max(n_clusters, 1), size=(n_boot, n_clusters)).astype(np.intp)


def bootstrap_mean_interval(
    values: ArrayLike,
    *,
    weights: ArrayLike | None = None,
    level: float = 0.9,
    indices: NDArray[np.intp] | None = None,
    n_boot: int = 2000,
    seed: int = 0,
) -> tuple[float, float] | None:
    """Percentile bootstrap interval of the (weighted) mean of per-cluster values.

    ``values`` holds one value per cluster (a pattern); the statistic of a resample of the
    clusters is sum(w v) / sum(w) over the drawn clusters, so a per-cluster rate with its
    cluster size as weight gives the pooled rate (events / flights) resampled by cluster.
    NaN values are missing (weight 0); resamples without any weight are left out. ``indices``:
    a matrix from :func:`bootstrap_indices` (else one is drawn with ``n_boot`` and ``seed``).
    Returns (lo, hi) at the central ``level``; None when no cluster has a value; (x, x) with
    a single such cluster.
    """
    v = np.asarray(values, dtype=float).ravel()
    w = np.ones_like(v) if weights is None else np.asarray(weights, dtype=float).ravel()
    if w.shape != v.shape or np.any(w < 0):
        raise ValueError("weights must be non-negative, one per value")
    if not (0 < level < 1):
        raise ValueError("level must be in (0, 1)")
    ok = np.isfinite(v) & (w > 0)
    if not ok.any():
        return None
    wv = np.where(ok, w * np.where(ok, v, 0.0), 0.0)
    w = np.where(ok, w, 0.0)
    idx = bootstrap_indices(v.size, n_boot=n_boot, seed=seed) if indices is None else indices
    if idx.ndim != 2 or idx.shape[1] != v.size:
        raise ValueError("indices must have one column per value")
    den = w[idx].sum(axis=1)
    keep = den > 0
    stat = wv[idx].sum(axis=1)[keep] / den[keep]
    lo, hi = np.percentile(stat, [50.0 * (1 - level), 50.0 * (1 + level)])
    return float(lo), float(hi)
