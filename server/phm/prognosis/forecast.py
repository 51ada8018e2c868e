"""Any health series plus a failure threshold in, RUL distribution out, by law averaging.

``forecast_rul(series, threshold, time=...)``: time in the caller's unit (any increasing
real numbers, uneven steps allowed); the RUL comes back in that unit. The degradation law is
not chosen by the caller: :mod:`.law_average` weighs constant-rate, affine-rate,
exponential, power-law, quadratic and onset (healthy, then growth) laws by their evidence
on the samples given, and the answer is their mixture. ``backtest_forecasts`` predicts at
chosen times, each from its prefix only (baseline and noise included).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .generic import BASELINE_SAMPLES, MIN_INFORMATIVE_SAMPLES, PriorDominatedWarning, as_seed
from .law_average import LawAverageConfig, fit_laws, rul_samples

__all__ = ["RulForecast", "backtest_forecasts", "forecast_rul"]


@dataclass(frozen=True)
class RulForecast:
    """RUL distribution after the sample at ``time`` (all times in the caller's unit)."""

    time: float
    samples: NDArray[np.float64] = field(repr=False)
    horizon: float
    law_weights: dict[str, float]
    prior_dominated: bool

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
    mixture = fit_laws(tau, (x - base) / span, cfg)
    gen = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(as_seed(rng))
    rul = rul_samples(mixture, cfg, gen) * observed
    return RulForecast(float(t[-1]), np.sort(rul), cfg.horizon_spans * observed,
                       mixture.law_weights, few)


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
