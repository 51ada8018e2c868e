"""Any health series plus a failure threshold in, RUL distribution out, by law averaging.

``forecast_rul(series, threshold, time=...)``: time in the caller's unit (any increasing
real numbers, uneven steps allowed); the RUL comes back in that unit. The degradation law is
not chosen by the caller: :mod:`.law_average` weighs constant-rate, affine-rate,
exponential, power-law, quadratic and onset (healthy, then growth) laws by their evidence
on the samples given, and the answer is their mixture. ``backtest_forecasts`` predicts at
chosen times, each from its prefix only (baseline and noise included).

The online guard: the series scores its own earlier forecasts. Each of
``guard_prefixes`` earlier prefixes (ending K, 2K, ... samples before the last one,
K = max(3, round(``guard_horizon`` x n))) is fitted as the forecast is, and the mean of
the last ``guard_window`` x K of the K samples that followed it is compared with the
mixture's predictive distribution of that mean (closed form,
:func:`.law_average.predictive_cdf`): outside its central 1 - alpha interval is a miss.
Oldest first, the misses drive the quantile-tracking step of conformal PID control
(Angelopoulos, Candes and Tibshirani, NeurIPS 2023; :func:`.generic.guard_step`, the step
the chain filter's guard takes on each side): w <- max(0, w + gain (miss - alpha)), and
the RUL distribution is widened by w in log(1 + RUL) around its median
(:func:`.generic.widen_about`): below it (1 + r) e^-w - 1, above it (1 + r) e^w - 1. A
series whose law changed under the fit, whose recent forecasts missed, gets a wider band.
One the mixture describes still misses about alpha of its forecasts, so about half such
series see a miss among six and w 0.15-0.27.
No draw: the guard is deterministic.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .generic import (
    BASELINE_SAMPLES,
    MIN_INFORMATIVE_SAMPLES,
    PriorDominatedWarning,
    as_seed,
    guard_step,
    widen_about,
)
from .law_average import LawAverageConfig, fit_laws, predictive_cdf, rul_samples

__all__ = ["RulForecast", "backtest_forecasts", "forecast_rul"]

#: the guard scores no prefix shorter than this (its own fit would be mostly the prior's)
GUARD_MIN_PREFIX = 2 * MIN_INFORMATIVE_SAMPLES
#: the guard's horizon is never shorter than this many samples
GUARD_MIN_HORIZON = 3


@dataclass(frozen=True)
class RulForecast:
    """RUL distribution after the sample at ``time`` (all times in the caller's unit).

    ``samples`` are the mixture's, widened by the online guard: ``guard_widening`` is w
    [log(1 + RUL)] (0: as the mixture says), ``guard_scored`` and ``guard_missed`` count
    the earlier forecasts of the series that the guard scored and those that missed.
    """

    time: float
    samples: NDArray[np.float64] = field(repr=False)
    horizon: float
    law_weights: dict[str, float]
    prior_dominated: bool
    guard_widening: float = 0.0
    guard_scored: int = 0
    guard_missed: int = 0

    def quantile(self, level: float) -> float:
        """RUL at ``level``, a fraction in (0, 1) (inf where it falls beyond the horizon)."""
        q = float(level)
        if not 0.0 < q < 1.0:
            raise ValueError(f"level must be a fraction in (0, 1), got {level!r} "
                             "(percentile() takes percent)")
        return float(np.quantile(self.samples, q, method="inverted_cdf"))

    def percentile(self, percent: float) -> float:
        """RUL at ``percent`` in (0, 100), e.g. ``percentile(5)``."""
        p = float(percent)
        if not 0.0 < p < 100.0:
            raise ValueError(f"percent must lie in (0, 100), got {percent!r}")
        return self.quantile(p / 100.0)

    @property
    def median(self) -> float:
        return self.quantile(0.5)

    @property
    def p_beyond_horizon(self) -> float:
        """Share of the distribution that does not fail within ``horizon``."""
        return float(np.mean(~np.isfinite(self.samples)))

    def interval(self, coverage: float) -> tuple[float, float]:
        """Central interval holding ``coverage`` (a fraction) of the distribution."""
        tail = (1.0 - float(coverage)) / 2.0
        return self.quantile(tail), self.quantile(1.0 - tail)


def _one_dimensional(values: ArrayLike, name: str) -> NDArray[np.float64]:
    """``values`` as a 1-D float array; a 2-D (or 0-D) one is refused, not flattened: a
    flattened table would read as one series of its rows laid end to end."""
    a = np.asarray(values, dtype=float)
    if a.ndim != 1:
        raise ValueError(f"{name} must be one-dimensional (one value per sample), got shape "
                         f"{a.shape}")
    return a


def _times(time: ArrayLike | None, n: int) -> NDArray[np.float64]:
    if time is None:
        return np.arange(n, dtype=float)
    t = _one_dimensional(time, "time")
    if t.size != n:
        raise ValueError(f"time has {t.size} values for {n} samples: give one per sample")
    if not np.all(np.isfinite(t)):
        raise ValueError("time must be finite")
    if np.any(np.diff(t) <= 0):
        raise ValueError("time must be strictly increasing")
    return t


def forecast_rul(series: ArrayLike, threshold: float, *, time: ArrayLike | None = None,
                 baseline: float | None = None, rng: np.random.Generator | int | None = None,
                 config: LawAverageConfig | None = None) -> RulForecast:
    """RUL distribution after the last sample, in the unit of ``time``.

    ``baseline`` is the healthy level; None takes the median of the first
    ``BASELINE_SAMPLES`` (5) samples. ``threshold`` may lie below the baseline (a fading
    capacity). ``time`` defaults to 0, 1, 2, ...; any strictly increasing real numbers.
    Fewer than ``MIN_INFORMATIVE_SAMPLES`` samples warn (:class:`PriorDominatedWarning`)
    and set ``prior_dominated``. ``rng``: a Generator, an (numpy) integer seed or None (0).
    """
    x = _one_dimensional(series, "series")
    if x.size < 2 or not np.all(np.isfinite(x)):
        raise ValueError("series must hold at least 2 finite samples")
    t = _times(time, x.size)
    base = float(np.median(x[:BASELINE_SAMPLES])) if baseline is None else float(baseline)
    span = float(threshold) - base
    if not math.isfinite(span) or span == 0.0:
        raise ValueError("threshold must differ from baseline")
    few = x.size < MIN_INFORMATIVE_SAMPLES
    if few:
        warnings.warn(f"{x.size} samples: the RUL comes mostly from the prior",
                      PriorDominatedWarning, stacklevel=2)
    cfg = config or LawAverageConfig()
    observed = float(t[-1] - t[0])
    tau = (t - t[0]) / observed
    severity = (x - base) / span
    mixture = fit_laws(tau, severity, cfg)
    gen = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(as_seed(rng))
    rul = np.sort(rul_samples(mixture, cfg, gen) * observed)
    horizon = cfg.horizon_spans * observed
    widening, scored, missed = _guard(t, severity, cfg)
    if widening > 0.0:
        median = float(np.quantile(rul, 0.5, method="inverted_cdf"))
        rul = widen_about(rul, median, widening)
        rul[rul > horizon] = np.inf  # widened past the horizon: beyond it, as the mixture says
    return RulForecast(float(t[-1]), rul, horizon, mixture.law_weights, few, widening,
                       scored, missed)


def _guard(t: NDArray[np.float64], severity: NDArray[np.float64], cfg: LawAverageConfig
           ) -> tuple[float, int, int]:
    """(widening w, forecasts scored, missed) of the online guard (module docstring) on the
    series (``t``, ``severity``): its earlier prefixes, oldest first, each scored on the
    samples that followed it."""
    n = t.size
    k = max(GUARD_MIN_HORIZON, round(cfg.guard_horizon * n))
    window = max(1, math.ceil(cfg.guard_window * k))
    alpha = cfg.guard_miss_rate
    widening, scored, missed = 0.0, 0, 0
    for j in range(cfg.guard_prefixes, 0, -1):
        end = n - 1 - j * k  # the prefix's last sample
        if end + 1 < GUARD_MIN_PREFIX:
            continue
        target = end + k
        span = float(t[end] - t[0])
        tau = (t[:target + 1] - t[0]) / span
        p = predictive_cdf(tau[:end + 1], severity[:end + 1], cfg,
                           tau[target + 1 - window:target + 1],
                           float(np.mean(severity[target + 1 - window:target + 1])))
        miss = not alpha / 2.0 <= p <= 1.0 - alpha / 2.0
        widening = guard_step(widening, miss, cfg.guard_gain, alpha)
        scored += 1
        missed += int(miss)
    return widening, scored, missed


def backtest_forecasts(series: ArrayLike, threshold: float, at: Sequence[float], *,
                       time: ArrayLike | None = None, baseline: float | None = None,
                       rng: np.random.Generator | int | None = None,
                       config: LawAverageConfig | None = None) -> list[RulForecast]:
    """The forecast at each time in ``at`` from the samples up to it only (the baseline,
    when not given, and the noise come from that prefix too)."""
    x = _one_dimensional(series, "series")
    t = _times(time, x.size)
    out = []
    for when in at:
        n = int(np.searchsorted(t, float(when), side="right"))
        if n == 0 or t[n - 1] != float(when):
            raise ValueError(f"no sample at time {when}")
        out.append(forecast_rul(x[:n], threshold, time=t[:n], baseline=baseline, rng=rng,
                                config=config))
    return out
