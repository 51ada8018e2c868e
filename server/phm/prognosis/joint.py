"""The degradation rate as part of the filter's state (joint state-parameter filter).

With ``PrognoserConfig.joint_rate`` every particle carries its own rate of the exponential law
dh/dk = r (h + c): the pair (h_i, r_i) is propagated and weighted together, so the rate's
uncertainty is the particles' spread. Particles whose rate is too slow fall behind the
measurements and lose weight; a fault faster than any design run pulls the cloud's rates up
by itself instead of fighting an RLS prior (Liu and West, "Combined parameter and state
estimation in simulation-based filtering", in Sequential Monte Carlo Methods in Practice, 2001;
Orchard and Vachtsevanos 2009 estimate the law's parameters the same way).

The rate is carried as its log-magnitude l = ln|r| (a rate is a scale: its spread is relative);
r has the sign of the law's offset c (r < 0 for a saturating law, c < -1).

- **Prior**: l ~ N(ln|r0|, s^2), r0 the design runs' median rate, s the spread of their
  log-rates (``rate_prior_log_std``, set by training).
- **Kernel** (Liu-West): after each update l_i <- a l_i + (1 - a) m + sqrt(1 - a^2) sd w_i,
  m and sd the weighted mean and standard deviation of l, a = ``rate_kernel_shrinkage``: the
  jitter keeps the rates diverse after resampling, the shrinkage keeps their weighted mean and
  spread unchanged, so the kernel adds no information of its own.
- **Prediction**: each particle rolls to the threshold with its own rate; no parameter draw.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from .degradation import exponential_law

if TYPE_CHECKING:  # pragma: no cover - typing only
    from .config import PrognoserConfig

__all__ = ["coefficients", "liu_west", "prior_log_rates", "rate_ratio", "signed_rates"]


def prior_log_rates(config: PrognoserConfig, rng: np.random.Generator) -> NDArray[np.float64]:
    """One log-magnitude of the rate per particle, drawn from the prior, shape (N,)."""
    centre = math.log(abs(config.theta0[1]))
    return centre + config.rate_log_std * rng.standard_normal(config.n_particles)


def signed_rates(config: PrognoserConfig, log_rates: NDArray[np.float64]) -> NDArray[np.float64]:
    """r_i from l_i: the magnitude with the sign of the law's offset."""
    sign = 1.0 if config.growth_offset > 0 else -1.0
    return sign * np.exp(log_rates)


def coefficients(config: PrognoserConfig, log_rates: NDArray[np.float64]
                 ) -> NDArray[np.float64]:
    """Growth-rate polynomial of every particle, (N, 2): [r_i c, r_i]."""
    rates = signed_rates(config, log_rates)
    return exponential_law(np.column_stack([np.zeros_like(rates), rates]), config.growth_offset)


def liu_west(log_rates: NDArray[np.float64], weights: NDArray[np.float64], shrinkage: float,
             rng: np.random.Generator) -> NDArray[np.float64]:
    """The kernel move of the log-rates: shrunk towards their weighted mean and jittered so that
    their weighted mean and variance are kept."""
    mean = float(np.dot(weights, log_rates))
    var = float(np.dot(weights, (log_rates - mean) ** 2))
    jitter = math.sqrt(max((1.0 - shrinkage**2) * var, 0.0))
    return (shrinkage * log_rates + (1.0 - shrinkage) * mean
            + jitter * rng.standard_normal(log_rates.size))


def rate_ratio(config: PrognoserConfig, log_rates: NDArray[np.float64],
               weights: NDArray[np.float64]) -> float:
    """The cloud's rate (weighted geometric mean) over the prior's centre |r0|: above 1 the
    fault runs faster than the design runs' median."""
    return math.exp(float(np.dot(weights, log_rates)) - math.log(abs(config.theta0[1])))
