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
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .degradation import rls_update

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

    def update(self, steps: Sequence[Any], resid_var: float, max_trace: float,
               prior_log_weights: NDArray[np.float64]) -> tuple[RateMixture, float]:
        """One RLS step per component (``steps``: its :class:`.laws.RlsMeasurement`), the
        weights by their predictive likelihoods; returns the mixture and the new residual
        variance (the components' own, averaged with the new weights)."""
        thetas, covs, variances, log_lik = [], [], [], []
        s2 = max(resid_var, 1e-300)
        for step in steps:
            spread = (step.forgetting + float(step.phi @ step.cov @ step.phi)) / step.forgetting
            err = step.y - float(step.phi @ step.theta)
            log_lik.append(-0.5 * (err * err / (s2 * spread) + math.log(s2 * spread)))
            theta, cov, var = rls_update(step.theta, step.cov, resid_var, step.phi, step.y,
                                         step.forgetting, max_trace)
            thetas.append(theta)
            covs.append(cov)
            variances.append(var)
        lam = steps[0].forgetting
        log_w = lam * self.log_weights + (1.0 - lam) * prior_log_weights + np.asarray(log_lik)
        log_w -= log_w.max()
        log_w -= math.log(np.exp(log_w).sum())
        mix = RateMixture(np.asarray(thetas), np.asarray(covs), log_w)
        return mix, float(mix.weights @ np.asarray(variances))

    def to_dict(self) -> dict[str, Any]:
        return {"theta": self.theta.tolist(), "cov": self.cov.tolist(),
                "log_weights": self.log_weights.tolist()}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> RateMixture:
        return cls(np.asarray(data["theta"], dtype=float), np.asarray(data["cov"], dtype=float),
                   np.asarray(data["log_weights"], dtype=float))
