"""Degradation laws: one class per ``rate_basis`` of :class:`~server.phm.prognosis.PrognoserConfig`.

A law says how severity grows and how its parameters are tuned (:mod:`.degradation` has the
equations)::

    dh/dk = g(h; theta) = max(theta . phi(h), min_rate)               [1/flight]

=============== ========================= ============ ==========================================
rate_basis      phi(h)                    theta        RLS measurement
=============== ========================= ============ ==========================================
``constant``    [1]                       (a,)         increment of the filtered severity
``affine``      [1, h]                    (a, b)       increment of the filtered severity
``quadratic``   [1, h, h^2]               (a, b, q)    increment of the filtered severity
``exponential`` [0, h + c] (c fixed)      (a, r)       log-level ln|h + c| = a + r k, whitened
=============== ========================= ============ ==========================================

Each class implements :class:`DegradationLaw`: its regressor and growth rate, the growth-rate
polynomial it hands to the propagation and the compiled prediction loop (:meth:`coefficients`:
every law is a polynomial in h there, so that loop needs no law code), its first trial and RLS
prior, what it does with the first measurement, the RLS measurement of each later update, and
the per-particle parameter draws of the long-term prediction. :data:`LAWS` maps the
``rate_basis`` string of a model document to its class; documents keep the string.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, ClassVar, NamedTuple, Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from .constants import CONSTANTS
from .degradation import (
    MID_LIFE,
    bound_mid_rate,
    exponential_law,
    growth_rate,
    level_measurement,
    log_level_observation,
    regressor,
)
from .mixture import RateMixture

if TYPE_CHECKING:  # pragma: no cover - typing only (config and filter import this module)
    from .config import PrognoserConfig
    from .filter import PrognoserState
    from .measurement import MeasurementModel

__all__ = [
    "LAWS",
    "AffineLaw",
    "ConstantLaw",
    "DegradationLaw",
    "ExponentialLaw",
    "PolynomialLaw",
    "QuadraticLaw",
    "RlsMeasurement",
    "law_for",
]


class RlsMeasurement(NamedTuple):
    """One RLS step as a law poses it: start from (theta, cov), regress y on phi with
    forgetting factor ``forgetting`` (:func:`~server.phm.prognosis.rls_update`)."""

    theta: NDArray[np.float64]
    cov: NDArray[np.float64]
    phi: NDArray[np.float64]
    y: float
    forgetting: float


@runtime_checkable
class DegradationLaw(Protocol):
    """What the filter and the predictor ask of a degradation law."""

    #: the ``rate_basis`` string of the law in a config / model document
    rate_basis: ClassVar[str]
    #: number of RLS parameters theta
    n_params: ClassVar[int]

    @classmethod
    def from_config(cls, config: PrognoserConfig) -> DegradationLaw:
        """The law with the shape parameters of ``config`` (e.g. the offset c)."""
        ...

    def regressor(self, h: NDArray[np.float64] | float) -> NDArray[np.float64]:
        """phi(h) with g(h; theta) = theta . phi(h) before the floor, shape h.shape + (p,)."""
        ...

    def coefficients(self, theta: NDArray[np.float64]) -> NDArray[np.float64]:
        """Ascending polynomial coefficients in h of theta . phi(h), for (p,) or (N, p)."""
        ...

    def growth_rate(self, h: NDArray[np.float64], theta: NDArray[np.float64],
                    min_rate: float) -> NDArray[np.float64]:
        """g(h; theta) [1/flight], floored at ``min_rate``."""
        ...

    def first_trial(self, initial_rate: float) -> tuple[float, ...]:
        """theta giving the rate ``initial_rate`` [1/flight] (config without initial_theta)."""
        ...

    def prior(self, config: PrognoserConfig) -> tuple[NDArray[np.float64], float]:
        """Initial RLS covariance P0 and residual variance s2_0."""
        ...

    def prior_mixture(self, config: PrognoserConfig) -> RateMixture:
        """The rate prior as a mixture of components (``config.rate_prior_tail`` > 0)."""
        ...

    def first_measurement(self, theta: NDArray[np.float64], cov: NDArray[np.float64],
                          severity: float, spread: float
                          ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(theta, P) after the first measurement, inverted to ``severity`` with standard
        deviation ``spread`` (the cloud is initialised around it; no RLS step)."""
        ...

    def rls_measurement(self, state: PrognoserState, estimate: float, feature: float,
                        dk: float, model: MeasurementModel, config: PrognoserConfig
                        ) -> RlsMeasurement:
        """The RLS step of an update at ``dk`` clock units after ``state``'s: ``estimate`` is
        the new filtered severity, ``feature`` the measured value."""
        ...

    def parameter_samples(self, state: PrognoserState, rng: np.random.Generator,
                          config: PrognoserConfig) -> NDArray[np.float64]:
        """One vector of growth-rate coefficients per particle for the long-term prediction,
        (N, len(coefficients)), within ``config.rate_bounds``."""
        ...


class PolynomialLaw:
    """g(h) = theta . [1, h, ..., h^(p-1)], tuned by RLS on the increments of the filtered
    severity, y = (h_hat[k] - h_hat[k - dk]) / dk against phi(h_hat[k - dk])."""

    rate_basis: ClassVar[str]
    n_params: ClassVar[int]

    @classmethod
    def from_config(cls, config: PrognoserConfig) -> PolynomialLaw:
        return cls()

    def __eq__(self, other: object) -> bool:
        return type(other) is type(self)

    def __hash__(self) -> int:
        return hash(type(self))

    def __repr__(self) -> str:
        return f"{type(self).__name__}()"

    def regressor(self, h: NDArray[np.float64] | float) -> NDArray[np.float64]:
        return regressor(h, self.n_params)

    def coefficients(self, theta: NDArray[np.float64]) -> NDArray[np.float64]:
        return theta

    def growth_rate(self, h: NDArray[np.float64], theta: NDArray[np.float64],
                    min_rate: float) -> NDArray[np.float64]:
        return growth_rate(h, theta, min_rate)

    def first_trial(self, initial_rate: float) -> tuple[float, ...]:
        return (initial_rate,) + (0.0,) * (self.n_params - 1)

    def prior(self, config: PrognoserConfig) -> tuple[NDArray[np.float64], float]:
        return np.eye(self.n_params) * config.rls_initial_cov, config.process_noise_std**2

    def prior_mixture(self, config: PrognoserConfig) -> RateMixture:
        raise ValueError("a mixture rate prior needs rate_basis 'exponential'")

    def first_measurement(self, theta: NDArray[np.float64], cov: NDArray[np.float64],
                          severity: float, spread: float
                          ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        return theta, cov

    def rls_measurement(self, state: PrognoserState, estimate: float, feature: float,
                        dk: float, model: MeasurementModel, config: PrognoserConfig
                        ) -> RlsMeasurement:
        assert state.last_estimate is not None  # an RLS step follows a first measurement
        phi = regressor(state.last_estimate, self.n_params)
        y = (estimate - state.last_estimate) / dk
        return RlsMeasurement(state.theta, state.cov, phi, y, config.rls_forgetting)

    def parameter_samples(self, state: PrognoserState, rng: np.random.Generator,
                          config: PrognoserConfig) -> NDArray[np.float64]:
        """theta_i ~ N(theta, c s2 P); with ``config.monotone_rate`` the severity-dependent
        terms are clipped at 0 and the constant term compensates, so that the rate at the
        current severity is unchanged. Without parameter uncertainty, the tuned theta itself
        (not bounded: as the filter has always done)."""
        n, p = config.n_particles, self.n_params
        scale = config.param_uncertainty_scale * state.resid_var
        if scale <= 0:
            return np.broadcast_to(state.theta, (n, p))
        cov = scale * state.cov
        jitter = 1e-15 * max(float(np.trace(cov)), 1e-30)
        chol = np.linalg.cholesky(cov + jitter * np.eye(p))
        theta = state.theta + rng.standard_normal((n, p)) @ chol.T
        if config.monotone_rate and p > 1:
            # keep each particle's rate at the current severity estimate (what the data pin down)
            h_ref = state.severity_mean
            clipped = np.maximum(theta[:, 1:], 0.0)
            powers = h_ref ** np.arange(1, p)
            theta[:, 0] += (theta[:, 1:] - clipped) @ powers
            theta[:, 1:] = clipped
        return bound_mid_rate(theta, config.rate_bounds)


class ConstantLaw(PolynomialLaw):
    """dh/dk = a: linear wear (Archard at a constant load)."""

    rate_basis = "constant"
    n_params = 1


class AffineLaw(PolynomialLaw):
    """dh/dk = a + b h: linear plus exponential growth (the default)."""

    rate_basis = "affine"
    n_params = 2


class QuadraticLaw(PolynomialLaw):
    """dh/dk = a + b h + q h^2: accelerating growth."""

    rate_basis = "quadratic"
    n_params = 3


class ExponentialLaw:
    """dh/dk = r (h + c) with the shape c fixed (``growth_offset``), theta = (a, r) of the
    log-level line ln|h + c| = a + r k, tuned by RLS on the severity *level*: the measurement
    inverted to severity, linearised about the filtered estimate and whitened by its noise
    (:func:`.degradation.log_level_observation`, :func:`.degradation.level_measurement`).
    c > 0 is growth (r > 0); c < -1 with r < 0 is growth that slows down towards -c."""

    rate_basis: ClassVar[str] = "exponential"
    n_params: ClassVar[int] = 2

    def __init__(self, offset: float) -> None:
        self.offset = float(offset)

    @classmethod
    def from_config(cls, config: PrognoserConfig) -> ExponentialLaw:
        return cls(config.growth_offset)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, ExponentialLaw) and other.offset == self.offset

    def __hash__(self) -> int:
        return hash((ExponentialLaw, self.offset))

    def __repr__(self) -> str:
        return f"ExponentialLaw(offset={self.offset!r})"

    def regressor(self, h: NDArray[np.float64] | float) -> NDArray[np.float64]:
        h = np.asarray(h, dtype=float)
        return np.stack([np.zeros_like(h), h + self.offset], axis=-1)

    def coefficients(self, theta: NDArray[np.float64]) -> NDArray[np.float64]:
        return exponential_law(theta, self.offset)

    def growth_rate(self, h: NDArray[np.float64], theta: NDArray[np.float64],
                    min_rate: float) -> NDArray[np.float64]:
        return growth_rate(h, self.coefficients(theta), min_rate)

    def first_trial(self, initial_rate: float) -> tuple[float, ...]:
        # a = 0 (re-set at the first measurement), r giving ``initial_rate`` at mid-life
        return (0.0, initial_rate / (MID_LIFE + self.offset))

    @staticmethod
    def rate_prior_std(config: PrognoserConfig) -> float:
        """Prior standard deviation of r [1/flight]."""
        if config.initial_rate_std is not None:
            return config.initial_rate_std
        return CONSTANTS.rate_prior_spread * abs(config.theta0[1])

    def prior(self, config: PrognoserConfig) -> tuple[NDArray[np.float64], float]:
        # the intercept's variance is set by the first measurement; the RLS runs on whitened
        # observations, so s2 starts at 1
        return np.diag([1.0, self.rate_prior_std(config) ** 2]), 1.0

    def first_measurement(self, theta: NDArray[np.float64], cov: NDArray[np.float64],
                          severity: float, spread: float
                          ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        y, sigma_y = log_level_observation(severity, severity, spread, self.offset)
        return np.array([y, theta[1]]), np.diag([sigma_y**2, cov[1, 1]])

    def rls_measurement(self, state: PrognoserState, estimate: float, feature: float,
                        dk: float, model: MeasurementModel, config: PrognoserConfig
                        ) -> RlsMeasurement:
        h_obs = model.invert_one(feature)
        sigma_h = model.severity_noise(estimate)
        y, sigma_y = log_level_observation(h_obs, estimate, sigma_h, self.offset)
        return RlsMeasurement(*level_measurement(state.theta, state.cov, dk, y, sigma_y,
                                                 config.rls_forgetting))

    def prior_mixture(self, config: PrognoserConfig) -> RateMixture:
        """The rate prior as a mixture: with ``config.rate_hypotheses``, one component per
        hypothesis (its rate prior and weight); else (``config.rate_prior_tail`` > 0) the
        normal of :meth:`prior` with weight 1 - tail, and that normal with its mean and
        standard deviation scaled by each of ``CONSTANTS.rate_tail_factors``, sharing the
        tail."""
        cov0, _ = self.prior(config)
        a0, r0 = config.theta0
        bank = config.rate_hypotheses
        if bank:
            cov = np.repeat(cov0[np.newaxis], len(bank), axis=0)
            cov[:, 1, 1] = [h.rate_std**2 for h in bank]
            weights = np.array([h.weight for h in bank])
            theta = np.column_stack([np.full(len(bank), a0), [h.rate for h in bank]])
            return RateMixture(theta, cov, np.log(weights / weights.sum()))
        factors = np.array((1.0,) + CONSTANTS.rate_tail_factors)
        tail = config.rate_prior_tail
        weights = np.r_[1.0 - tail, np.full(factors.size - 1, tail / (factors.size - 1))]
        theta = np.column_stack([np.full(factors.size, a0), r0 * factors])
        cov = np.repeat(cov0[np.newaxis], factors.size, axis=0)
        cov[:, 1, 1] *= factors**2
        return RateMixture(theta, cov, np.log(weights))

    def parameter_samples(self, state: PrognoserState, rng: np.random.Generator,
                          config: PrognoserConfig) -> NDArray[np.float64]:
        """r_i ~ N(r, c s2 P_rr) with s2 floored at 1 (the misfit factor inflates, never
        shrinks, the whitened covariance), kept on the growth side (r has the sign of c).
        With a mixture prior each particle first draws its component by the weights."""
        n = config.n_particles
        scale = config.param_uncertainty_scale * max(state.resid_var, 1.0)
        if state.mixture is None:
            mean, var = state.theta[1], scale * state.cov[1, 1]
        else:
            mix = state.mixture
            comp = rng.choice(mix.weights.size, size=n, p=mix.weights)
            mean, var = mix.theta[comp, 1], scale * mix.cov[comp, 1, 1]
        rate = mean + np.sqrt(np.maximum(var, 0.0)) * rng.standard_normal(n)
        rate = np.maximum(rate, 0.0) if self.offset > 0 else np.minimum(rate, 0.0)
        theta = np.column_stack([np.zeros(n), rate])
        return bound_mid_rate(self.coefficients(theta), config.rate_bounds)


#: the laws by ``rate_basis`` (the string a config and a model document carry)
LAWS: dict[str, type[DegradationLaw]] = {
    law.rate_basis: law for law in (ConstantLaw, AffineLaw, QuadraticLaw, ExponentialLaw)
}


def law_for(rate_basis: str) -> type[DegradationLaw]:
    """The law class of a ``rate_basis`` string; ValueError for an unknown one."""
    try:
        return LAWS[rate_basis]
    except KeyError:
        raise ValueError(
            f"rate_basis must be one of {sorted(LAWS)}, got {rate_basis!r}") from None
