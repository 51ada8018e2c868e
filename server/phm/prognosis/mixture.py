"""A mixture prior on the degradation rate: one RLS per component, weighted by its evidence.

A normal prior on the rate r, centred on the design runs' median, is light-tailed: a fault three
times faster than any in design sits many prior standard deviations out, and the RLS needs
tens of flights to leave the prior while the RUL is predicted at several times the truth. With
a mixture prior, sum_k w_k N(theta_k, P_k), the linear-Gaussian RLS stays exact: the posterior is
the mixture of the components' own RLS posteriors, each weight multiplied by the predictive
likelihood of every new measurement under its component (multiple-model adaptive estimation,
Magill 1965; Bar-Shalom, Li & Kirubarajan 2001, section 11.6)::

    e_k = y - phi . theta_k,   S_k = s2 (lambda + phi' P_k phi) / lambda
    log w_k <- lambda log w_k + (1 - lambda) log w0_k - (e_k^2 / S_k + ln S_k) / 2,  normalised

The weights forget at the RLS's own rate, towards the prior weights w0, so a component that
lost its weight early can win it back when the fault changes pace. The filter propagates its
particles with the mixture's mean and draws the prediction's rates from the mixture
(:meth:`.laws.ExponentialLaw.parameter_samples`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from .degradation import rls_update_batch

if TYPE_CHECKING:  # pragma: no cover - typing only (laws imports this module)
    from .laws import RlsMeasurement

__all__ = ["RateMixture"]


@dataclass(frozen=True)
class RateMixture:
    """The RLS components of a mixture rate prior: parameters (K, p), normalised covariances
    (K, p, p) and normalised log-weights (K,)."""

    theta: NDArray[np.float64]
    cov: NDArray[np.float64]
    log_weights: NDArray[np.float64]

    def __post_init__(self) -> None:
        k = self.log_weights.shape
        if self.theta.ndim != 2 or self.theta.shape[:1] != k or \
                self.cov.shape != (k[0], self.theta.shape[1], self.theta.shape[1]):
            raise ValueError("mixture: theta (K, p), cov (K, p, p) and log_weights (K,) needed")

    @property
    def weights(self) -> NDArray[np.float64]:
        w = np.exp(self.log_weights - self.log_weights.max())
        return w / w.sum()

    def moments(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Mean (p,) and covariance (p, p) of the mixture (what one RLS would carry)."""
        w = self.weights
        mean = w @ self.theta
        dev = self.theta - mean
        cov = np.einsum("k,kij->ij", w, self.cov) + (dev * w[:, np.newaxis]).T @ dev
        return mean, 0.5 * (cov + cov.T)

    def update(self, step: RlsMeasurement, resid_var: float, max_trace: float,
               prior_log_weights: NDArray[np.float64]) -> tuple[RateMixture, float]:
        """One RLS step of every component at once (``step``: a :class:`.laws.RlsMeasurement`
        whose theta (K, p) and cov (K, p, p) are the components' and whose regressor,
        observation and forgetting they share), the weights by their predictive likelihoods;
        returns the mixture and the new residual variance (the components' own, averaged
        with the new weights)."""
        s2 = max(resid_var, 1e-300)
        lam = step.forgetting
        # the predictive spread of each component, before its update
        spread = (lam + (step.phi @ step.cov) @ step.phi) / lam
        err = step.y - step.theta @ step.phi
        # math.log, not np.log: numpy's vectorised log can differ in the last bit, and the
        # weights are those of one RLS per component, bit for bit
        var = s2 * spread
        log_lik = -0.5 * (err * err / var + np.array([math.log(v) for v in var]))
        theta, cov, variances = rls_update_batch(step.theta, step.cov, resid_var, step.phi,
                                                 step.y, lam, max_trace)
        log_w = lam * self.log_weights + (1.0 - lam) * prior_log_weights + log_lik
        log_w -= log_w.max()
        log_w -= math.log(np.exp(log_w).sum())
        mix = RateMixture(theta, cov, log_w)
        return mix, float(mix.weights @ variances)

    def to_dict(self) -> dict[str, Any]:
        return {"theta": self.theta.tolist(), "cov": self.cov.tolist(),
                "log_weights": self.log_weights.tolist()}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> RateMixture:
        return cls(np.asarray(data["theta"], dtype=float), np.asarray(data["cov"], dtype=float),
                   np.asarray(data["log_weights"], dtype=float))
