"""Generic interface: any health-indicator series plus a failure threshold in, RUL out.

The series is normalised to a severity with the failure threshold at 1.0::

    severity = (x - baseline) / (threshold - baseline)

so an indicator that *decreases* toward its threshold (e.g. a capacity) works by giving a
threshold below the baseline. Time: one sample per flight unless ``flight_index`` is given;
``flight_hours`` (duration of each flight [h]) are carried alongside when given. If no
measurement noise is given it is estimated from the series (robust MAD of second differences,
which removes a smooth trend: var(d2 x) = 6 sigma^2 for white noise).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .config import PrognoserConfig
from .constants import CONSTANTS
from .filter import ParticleFilterPrognoser, PrognoserState
from .measurement import MeasurementModel
from .predictor import RulDistribution

__all__ = ["GENERIC_CONFIG", "estimate_noise_std", "predict_rul", "track_rul"]

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


def _seed(rng: np.random.Generator | int | None) -> int:
    if rng is None:
        return 0
    if isinstance(rng, np.random.Generator):
        return int(rng.integers(0, 2**63 - 1))
    if isinstance(rng, bool) or not isinstance(rng, int):
        raise ValueError("rng must be a numpy Generator, an int seed or None")
    return rng


def track_rul(
    series: ArrayLike,
    threshold: float,
    *,
    baseline: float = 0.0,
    flight_index: ArrayLike | None = None,
    flight_hours: ArrayLike | None = None,
    noise_std: float | None = None,
    config: PrognoserConfig | None = None,
    rng: np.random.Generator | int | None = None,
    predict_at: Sequence[int] | None = None,
) -> tuple[list[RulDistribution], PrognoserState]:
    """Run the filter over a series; predict at the flights in ``predict_at`` (default: all).

    Returns the RUL distributions (one per prediction, in order) and the final filter state.
    ``noise_std`` is in the unit of the series.
    """
    x = np.asarray(series, dtype=float).ravel()
    if x.size == 0 or not np.all(np.isfinite(x)):
        raise ValueError("series must be non-empty and finite")
    span = float(threshold) - float(baseline)
    if not math.isfinite(span) or span == 0.0:
        raise ValueError("threshold must differ from baseline")
    k: NDArray[np.int64] = (
        np.arange(x.size)
        if flight_index is None
        else np.asarray(flight_index, dtype=np.int64).ravel()
    )
    if k.shape != x.shape or np.any(np.diff(k) <= 0):
        raise ValueError("flight_index must be strictly increasing, one per sample")
    hours = None if flight_hours is None else np.asarray(flight_hours, dtype=float).ravel()
    if hours is not None and hours.shape != x.shape:
        raise ValueError("flight_hours must have one value per sample")
    severity = (x - baseline) / span
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
    baseline: float = 0.0,
    flight_index: ArrayLike | None = None,
    flight_hours: ArrayLike | None = None,
    noise_std: float | None = None,
    config: PrognoserConfig | None = None,
    rng: np.random.Generator | int | None = None,
) -> RulDistribution:
    """RUL distribution [flight] after the last sample of ``series`` (see :func:`track_rul`)."""
    x = np.asarray(series, dtype=float).ravel()
    k = np.arange(x.size) if flight_index is None else np.asarray(flight_index).ravel()
    dists, _ = track_rul(
        x,
        threshold,
        baseline=baseline,
        flight_index=k,
        flight_hours=flight_hours,
        noise_std=noise_std,
        config=config,
        rng=rng,
        predict_at=[int(k[-1])] if k.size else [],
    )
    return dists[-1]
