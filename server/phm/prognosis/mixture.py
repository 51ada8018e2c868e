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

Those predictive weights favour the component whose RLS adapts best, not the one whose band
holds the rate the measurements show: each RLS forgets its own prior, so after a few tens of
flights every component finds about the same rate and the weights follow the spread of each
one's predictions (a wear fault of 100-240 flights led "fast" while its rate lay in the
medium band). A bank weighed by ``"evidence"`` (``PrognoserConfig.rate_weighting``,
:class:`BandEvidence`) keeps each band's prior whole, as it stood after the first
measurement (theta_k, P_k in the frame of that flight), and discounts only the measurements,
at the RLS's forgetting: with g_i the regressor carried back to that frame and lambda_i the
forgetting since measurement i,

    J = sum_i lambda_i g_i g_i',   b = sum_i lambda_i g_i y_i
    L_k = P_k^-1 + J / s2,   m_k = L_k^-1 (P_k^-1 theta_k + b / s2)
    log w_k = log w0_k - (theta_k' P_k^-1 theta_k - m_k' L_k m_k) / 2
              - (ln det P_k + ln det L_k) / 2,  normalised

the log-evidence of each band's prior for the discounted measurements (terms common to every
band dropped). s2 is the RLS residual variance floored at 1 (as the prediction floors it): a
misfit of the law makes the measurements say less, not the band's prior say more (in the
RLS's own normalisation the prior scales with s2; a chain's misfit of s2 = 15 then widened
every band's prior four-fold and the narrowest band won by its Occam factor alone). The
components' own RLS, which the prediction draws from, are unchanged.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from .degradation import level_shift, rls_update_batch

if TYPE_CHECKING:  # pragma: no cover - typing only (laws imports this module)
    from .laws import RlsMeasurement

__all__ = ["BandEvidence", "RateMixture"]


@dataclass(frozen=True)
class BandEvidence:
    """What a bank weighed by evidence keeps: every band's prior after the first measurement,
    (K, p) and (K, p, p), in the frame of that flight; the measurements' discounted
    information ``info`` (p, p) and ``score`` (p,) in that frame; the clock since [units]."""

    prior_theta: NDArray[np.float64]
    prior_cov: NDArray[np.float64]
    info: NDArray[np.float64]
    score: NDArray[np.float64]
    clock: float = 0.0

    @classmethod
    def start(cls, theta: NDArray[np.float64], cov: NDArray[np.float64]) -> BandEvidence:
        """The bands' priors ``theta`` (K, p), ``cov`` (K, p, p) at the first measurement."""
        p = theta.shape[1]
        return cls(np.array(theta, dtype=float), np.array(cov, dtype=float),
                   np.zeros((p, p)), np.zeros(p))

    def add(self, phi: NDArray[np.float64], y: float, forgetting: float, dk: float
            ) -> BandEvidence:
        """One measurement ``y`` on regressor ``phi`` ``dk`` clock units on, the information
        so far discounted by ``forgetting``."""
        clock = self.clock + dk
        g = level_shift(clock).T @ phi  # the regressor in the first measurement's frame
        return BandEvidence(self.prior_theta, self.prior_cov,
                            forgetting * self.info + np.outer(g, g),
                            forgetting * self.score + g * y, clock)

    def log_weights(self, prior_log_weights: NDArray[np.float64], resid_var: float
                    ) -> NDArray[np.float64]:
        """Normalised log-weights: the prior weights times each band's evidence."""
        s2 = max(resid_var, 1.0)
        prec = np.linalg.inv(self.prior_cov)
        eta = prec @ self.prior_theta[..., np.newaxis] + (self.score / s2)[:, np.newaxis]
        post_prec = prec + self.info / s2
        mean = np.linalg.solve(post_prec, eta)
        quad = (np.einsum("ki,kij,kj->k", self.prior_theta, prec, self.prior_theta)
                - np.einsum("kij,kij->k", mean, eta))
        log_det = np.linalg.slogdet(self.prior_cov)[1] + np.linalg.slogdet(post_prec)[1]
        log_w = prior_log_weights - 0.5 * quad - 0.5 * log_det
        log_w -= log_w.max()
        return log_w - math.log(np.exp(log_w).sum())

    def to_dict(self) -> dict[str, Any]:
        return {"prior_theta": self.prior_theta.tolist(), "prior_cov": self.prior_cov.tolist(),
                "info": self.info.tolist(), "score": self.score.tolist(), "clock": self.clock}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> BandEvidence:
        def arr(key: str) -> NDArray[np.float64]:
            return np.asarray(data[key], dtype=float)

        return cls(arr("prior_theta"), arr("prior_cov"), arr("info"), arr("score"),
                   float(data["clock"]))


@dataclass(frozen=True)
class RateMixture:
    """The RLS components of a mixture rate prior: parameters (K, p), normalised covariances
    (K, p, p) and normalised log-weights (K,)."""

    theta: NDArray[np.float64]
    cov: NDArray[np.float64]
    log_weights: NDArray[np.float64]
    evidence: BandEvidence | None = None

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
               prior_log_weights: NDArray[np.float64], dk: float
               ) -> tuple[RateMixture, float]:
        """One RLS step of every component at once (``step``: a :class:`.laws.RlsMeasurement`
        whose theta (K, p) and cov (K, p, p) are the components' and whose regressor,
        observation and forgetting they share, ``dk`` clock units after the last), the
        weights by their predictive likelihoods or, with :attr:`evidence`, by each band's
        evidence; returns the mixture and the new residual variance (the components' own,
        averaged with the new weights)."""
        theta, cov, variances = rls_update_batch(step.theta, step.cov, resid_var, step.phi,
                                                 step.y, step.forgetting, max_trace)
        if self.evidence is None:
            log_w = self._predictive_log_weights(step, resid_var, prior_log_weights)
            mix = RateMixture(theta, cov, log_w)
        else:
            evidence = self.evidence.add(step.phi, step.y, step.forgetting, dk)
            # read with the components' residual variance averaged with the weights they had
            # (the new ones need it)
            log_w = evidence.log_weights(prior_log_weights, float(self.weights @ variances))
            mix = RateMixture(theta, cov, log_w, evidence)
        return mix, float(mix.weights @ variances)

    def _predictive_log_weights(self, step: RlsMeasurement, resid_var: float,
                                prior_log_weights: NDArray[np.float64]) -> NDArray[np.float64]:
        """The weights times each component's predictive likelihood of ``step``'s
        observation, forgotten at the RLS's rate towards the prior weights, normalised."""
        lam = step.forgetting
        # the predictive spread of each component, before its update
        spread = (lam + (step.phi @ step.cov) @ step.phi) / lam
        err = step.y - step.theta @ step.phi
        # math.log, not np.log: numpy's vectorised log can differ in the last bit, and the
        # weights are those of one RLS per component, bit for bit
        var = max(resid_var, 1e-300) * spread
        log_lik = -0.5 * (err * err / var + np.array([math.log(v) for v in var]))
        log_w = lam * self.log_weights + (1.0 - lam) * prior_log_weights + log_lik
        log_w -= log_w.max()
        return log_w - math.log(np.exp(log_w).sum())

    def to_dict(self) -> dict[str, Any]:
        out = {"theta": self.theta.tolist(), "cov": self.cov.tolist(),
               "log_weights": self.log_weights.tolist()}
        if self.evidence is not None:  # absent otherwise: states without it read as before
            out["evidence"] = self.evidence.to_dict()
        return out

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> RateMixture:
        evidence = data.get("evidence")
        return cls(np.asarray(data["theta"], dtype=float), np.asarray(data["cov"], dtype=float),
                   np.asarray(data["log_weights"], dtype=float),
                   None if evidence is None else BandEvidence.from_dict(evidence))
