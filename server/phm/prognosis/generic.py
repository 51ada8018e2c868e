"""Generic interface: any health-indicator series plus a failure threshold in, RUL out.

The series is normalised to a severity with the failure threshold at 1.0::

    severity = (x - baseline) / (threshold - baseline)

so an indicator that *decreases* toward its threshold (e.g. a capacity) works by giving a
threshold below the baseline; without a ``baseline`` the median of the first 5 samples is the
healthy level. Time: one sample per step unless ``time`` gives each sample's step (whole
numbers; the aircraft chain calls it ``flight_index``); ``flight_hours`` (duration of each
step [h]) are carried alongside when given. If no
measurement noise is given it is estimated from the series (robust MAD of second differences,
which removes a smooth trend: var(d2 x) = 6 sigma^2 for white noise).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .config import PrognoserConfig
from .constants import CONSTANTS
from .filter import ParticleFilterPrognoser, PrognoserState
from .measurement import MeasurementModel
from .predictor import RulDistribution

__all__ = ["GENERIC_CONFIG", "BASELINE_SAMPLES", "MIN_INFORMATIVE_SAMPLES",
           "PriorDominatedWarning", "backtest_rul", "estimate_noise_std", "predict_rul",
           "track_rul"]

#: the config of :func:`track_rul` / :func:`predict_rul` when none is given: the defaults with
#: the process noise of a smooth synthetic health indicator, 0.004 / sqrt(flight) (the trained
#: chain's 0.01 follows faster-than-prior faults and costs smooth series accuracy:
#: docs/TUNING.md, Prognosis)
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


def _seed(rng: np.random.Generator | int | np.integer | None) -> int:
    if rng is None:
        return 0
    if isinstance(rng, np.random.Generator):
        return int(rng.integers(0, 2**63 - 1))
    if isinstance(rng, bool) or not isinstance(rng, int | np.integer):
        raise ValueError("rng must be a numpy Generator, an integer seed or None")
    return int(rng)


class PriorDominatedWarning(UserWarning):
    """Too few samples for the data to move the prior: the RUL is mostly the prior's."""


#: fewer samples than this and the answer is mostly the prior's (a warning says so)
MIN_INFORMATIVE_SAMPLES = 5
#: samples whose median stands for the healthy level when no baseline is given
BASELINE_SAMPLES = 5


def _series(series: ArrayLike) -> NDArray[np.float64]:
    x = np.asarray(series, dtype=float).ravel()
    if x.size == 0 or not np.all(np.isfinite(x)):
        raise ValueError("series must be non-empty and finite")
    return x


def _times(time: ArrayLike | None, n: int) -> NDArray[np.int64]:
    """Sample times as integer steps: given ones checked (whole numbers, one per sample,
    strictly increasing), else 0, 1, 2, ..."""
    if time is None:
        return np.arange(n, dtype=np.int64)
    t = np.asarray(time, dtype=float).ravel()
    if t.size != n:
        raise ValueError(f"time has {t.size} values for {n} samples: give one per sample")
    if not np.all(np.isfinite(t)) or np.any(t != np.round(t)):
        raise ValueError("time must be whole numbers of steps (flights, cycles, ...)")
    if np.any(np.diff(t) <= 0):
        raise ValueError("time must be strictly increasing")
    return t.astype(np.int64)


def _baseline_of(x: NDArray[np.float64], baseline: float | None) -> float:
    return float(np.median(x[:BASELINE_SAMPLES])) if baseline is None else float(baseline)


def _pick_time(time: ArrayLike | None, flight_index: ArrayLike | None) -> ArrayLike | None:
    if time is not None and flight_index is not None:
        raise ValueError("give time or its aircraft name flight_index, not both")
    return time if time is not None else flight_index


def track_rul(
    series: ArrayLike,
    threshold: float,
    *,
    baseline: float | None = None,
    time: ArrayLike | None = None,
    flight_index: ArrayLike | None = None,
    flight_hours: ArrayLike | None = None,
    noise_std: float | None = None,
    config: PrognoserConfig | None = None,
    rng: np.random.Generator | int | None = None,
    predict_at: Sequence[int] | None = None,
) -> tuple[list[RulDistribution], PrognoserState]:
    """Run the filter over a series; predict at the times in ``predict_at`` (default: all).

    ``baseline`` is the indicator's healthy level (severity 0); None takes the median of the
    first ``BASELINE_SAMPLES`` (5) samples. ``time`` gives each sample's time in whole steps
    (default 0, 1, 2, ...; ``flight_index`` is its name in the aircraft chain); RULs are in
    those steps. ``noise_std`` is in the unit of the series; None estimates it from the
    *whole* series, so a backtest that must not see the future uses :func:`backtest_rul`.
    Returns the RUL distributions (one per prediction, in order) and the final filter state.
    Fewer than ``MIN_INFORMATIVE_SAMPLES`` samples warn (:class:`PriorDominatedWarning`).
    """
    x = _series(series)
    base = _baseline_of(x, baseline)
    span = float(threshold) - base
    if not math.isfinite(span) or span == 0.0:
        raise ValueError("threshold must differ from baseline")
    k = _times(_pick_time(time, flight_index), x.size)
    hours = None if flight_hours is None else np.asarray(flight_hours, dtype=float).ravel()
    if hours is not None and hours.shape != x.shape:
        raise ValueError("flight_hours must have one value per sample")
    if x.size < MIN_INFORMATIVE_SAMPLES:
        warnings.warn(f"{x.size} samples: the RUL comes mostly from the prior",
                      PriorDominatedWarning, stacklevel=2)
    severity = (x - base) / span
    if noise_std is None:
        sigma = (estimate_noise_std(severity) if x.size >= 4
                 else CONSTANTS.short_series_noise)
    else:
        if not (math.isfinite(noise_std) and noise_std > 0):
            raise ValueError("noise_std must be finite and > 0")
        sigma = noise_std / abs(span)
    cfg = config or GENERIC_CONFIG
    model = MeasurementModel.identity(sigma)
    pf = ParticleFilterPrognoser(cfg, model)
    state = pf.initial_state(cfg, model, _seed(rng))
    wanted = set(k.tolist()) if predict_at is None else {int(v) for v in predict_at}
    out: list[RulDistribution] = []
    for i in range(x.size):
        state = pf.update(
            state,
            float(severity[i]),
            int(k[i]),
            flight_hours=None if hours is None else float(hours[i]),
        )
        if int(k[i]) in wanted:
            out.append(pf.predict(state))
    return out, state


def predict_rul(
    series: ArrayLike,
    threshold: float,
    *,
    baseline: float | None = None,
    time: ArrayLike | None = None,
    flight_index: ArrayLike | None = None,
    flight_hours: ArrayLike | None = None,
    noise_std: float | None = None,
    config: PrognoserConfig | None = None,
    rng: np.random.Generator | int | None = None,
) -> RulDistribution:
    """RUL distribution after the last sample of ``series``, in the steps of ``time``
    (see :func:`track_rul` for every argument)."""
    x = _series(series)
    k = _times(_pick_time(time, flight_index), x.size)
    dists, _ = track_rul(x, threshold, baseline=_baseline_of(x, baseline), time=k,
                         flight_hours=flight_hours, noise_std=noise_std, config=config,
                         rng=rng, predict_at=[int(k[-1])])
    return dists[-1]


def backtest_rul(
    series: ArrayLike,
    threshold: float,
    at: Sequence[int],
    *,
    baseline: float | None = None,
    time: ArrayLike | None = None,
    noise_std: float | None = None,
    config: PrognoserConfig | None = None,
    rng: np.random.Generator | int | None = None,
) -> list[RulDistribution]:
    """The RUL at each time in ``at`` from the samples up to that time only: the baseline
    and the noise (when not given) come from that prefix too, so nothing of the future
    leaks into a prediction (what a backtest needs; :func:`track_rul` sees the whole series).
    """
    x = _series(series)
    k = _times(time, x.size)
    out = []
    for t in at:
        n = int(np.searchsorted(k, int(t), side="right"))
        if n == 0 or int(k[n - 1]) != int(t):
            raise ValueError(f"no sample at time {t}")
        out.append(predict_rul(x[:n], threshold, baseline=baseline, time=k[:n],
                               noise_std=noise_std, config=config, rng=rng))
    return out
