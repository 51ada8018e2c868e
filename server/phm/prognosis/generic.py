"""What the generic interface (:func:`.forecast.forecast_rul`: any health series plus a failure
threshold in, RUL distribution out) shares: the healthy-level and few-samples rules, the seed
rule, the robust noise estimate of a trending series (MAD of second differences, which
removes a smooth trend: var(d2 x) = 6 sigma^2 for white noise), and the online guard's step
and widening (:func:`guard_step`, :func:`widen_about`: pure, for any guard to use).
``GENERIC_CONFIG`` is the particle filter's config for smooth synthetic health indicators (its
tests and ``bench/bench_prognosis.py``).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from .config import PrognoserConfig

__all__ = ["GENERIC_CONFIG", "BASELINE_SAMPLES", "MIN_INFORMATIVE_SAMPLES",
           "PriorDominatedWarning", "as_seed", "estimate_noise_std", "guard_step",
           "widen_about"]

#: the particle filter on a smooth synthetic health indicator: the defaults with a process
#: noise of 0.004 / sqrt(flight) (the trained chain's 0.01 follows faster-than-prior faults and
#: costs smooth series accuracy: docs/TUNING.md, Prognosis)
GENERIC_CONFIG = PrognoserConfig(process_noise_std=0.004)


def estimate_noise_std(series: ArrayLike) -> float:
    """Robust white-noise standard deviation of a trending series (same unit as the series)."""
    x = np.asarray(series, dtype=float)
    if x.size < 4:
        raise ValueError("need at least 4 samples to estimate the noise")
    d2 = np.diff(x, n=2)
    mad = float(np.median(np.abs(d2 - np.median(d2))))
    sigma = 1.4826 * mad / math.sqrt(6.0)
    scale = float(np.max(np.abs(x))) or 1.0
    return max(sigma, 1e-6 * scale)


def as_seed(rng: np.random.Generator | int | np.integer | None) -> int:
    """An integer seed from a Generator (one draw), an integer (numpy's too) or None (0)."""
    if rng is None:
        return 0
    if isinstance(rng, np.random.Generator):
        return int(rng.integers(0, 2**63 - 1))
    if isinstance(rng, bool) or not isinstance(rng, int | np.integer):
        raise ValueError("rng must be a numpy Generator, an integer seed or None")
    return int(rng)


def guard_step(widening: float, miss: bool, gain: float, miss_rate: float) -> float:
    """One scored forecast of an online guard: the quantile-tracking step of conformal PID
    control (Angelopoulos, Candes and Tibshirani, NeurIPS 2023), floored at 0,
    ``max(0, w + gain (miss - miss_rate))`` [log(1 + RUL)]."""
    return max(0.0, widening + gain * (float(miss) - miss_rate))


def widen_about(values: ArrayLike, centre: float, margin: float,
                upper_margin: float | None = None) -> np.ndarray:
    """RUL ``values`` moved out from ``centre`` (the median) in log(1 + RUL): below it to
    (1 + v) e^-margin - 1 (not below 0, nor above the centre), above it to
    (1 + v) e^upper_margin - 1 (``upper_margin`` defaults to ``margin``); the centre itself
    and inf stay. The band ends of :func:`.calibration.widen`, applied to any values (a
    forecast's samples)."""
    v = np.asarray(values, dtype=float)
    up = margin if upper_margin is None else upper_margin
    with np.errstate(invalid="ignore"):
        return np.where(v < centre, np.clip(np.expm1(np.log1p(v) - margin), 0.0, centre),
                        np.where(v > centre, np.expm1(np.log1p(v) + up), v))


class PriorDominatedWarning(UserWarning):
    """Too few samples for the data to move the prior: the RUL is mostly the prior's."""


#: fewer samples than this and the answer is mostly the prior's (a warning says so)
MIN_INFORMATIVE_SAMPLES = 5
#: samples whose median stands for the healthy level when no baseline is given
BASELINE_SAMPLES = 5
