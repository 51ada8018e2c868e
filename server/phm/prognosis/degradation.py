"""Degradation model: severity growth per flight, tuned online by recursive least squares (RLS).

Model (per flight, k in flights, h normalised severity, threshold 1.0)::

    h[k+dk] = h[k] + dk * g(h[k]; theta) + q * sqrt(dk) * w,     w ~ N(0, 1)
    g(h; theta) = max(theta . phi(h), min_rate)                     [1/flight]
    phi(h) = [1] ("constant"), [1, h] ("affine"), [1, h, h^2] ("quadratic")

The rate is linear in theta, so theta is tracked by exponentially weighted RLS (forgetting factor
lambda) on the increments of the *filtered* severity estimate, y = (h_hat[k] - h_hat[k-dk]) / dk,
regressed on phi(h_hat[k-dk]): the time-variant, auto-tuned degradation model of the paper
(section 4.2; Orchard and Vachtsevanos 2009). Besides theta and its normalised covariance P, the
RLS keeps an exponentially weighted residual variance s2, so that s2 * P approximates the
covariance of theta (used to draw one parameter vector per particle in the long-term prediction).

The ``"exponential"`` law dh/dk = r (h + c), with the shape c fixed per fault mode (learned on the
design runs), is the simulator's and the physics' form: Arrhenius insulation damage and magnet
loss grow in proportion to the damage done (small c), Archard wear at a steady load grows
linearly (large c). With c < -1 and r < 0 the same law is growth that slows down towards -c:
Archard wear of a drive whose share of the load falls as it wears. Its rate r is tuned by RLS
on the severity *level* instead of its increments: ln|h + c| = a + r k is a straight line in
the flight index, so r is the slope of a weighted linear regression of the log-level on k.
Increments of the filtered severity are a
noisy, lagged derivative and leave r to the prior for much of a life; the level uses every
measurement since the alarm with its own independent noise. The intercept is kept at the latest
flight (a change of coordinates, exact for RLS): before each update ``a <- a + r dk`` and
``P <- F P F'`` with F = [[1, dk], [0, 1]], then the regressor is [1, 0]. The observation is
the measurement inverted to severity, linearised about the filtered estimate h_f:
y = ln|h_f + c| + (h_obs - h_f) / (h_f + c), with standard deviation sigma_h / |h_f + c|; the
RLS runs on y / sigma_y, so P is the parameter covariance itself and s2 the misfit factor.

All functions are pure and work on small numpy arrays; nothing here is random. The law
classes of :mod:`.laws` (one per ``rate_basis``) are built from them.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from .constants import CONSTANTS

__all__ = [
    "MID_LIFE",
    "MIN_LEVEL_GAP",
    "bound_mid_rate",
    "exponential_law",
    "growth_rate",
    "level_measurement",
    "level_rls_update",
    "level_shift",
    "log_level_observation",
    "regressor",
    "rls_update",
    "rls_update_batch",
]


#: smallest |h + c| of the log-level observation of a saturating law [-]
MIN_LEVEL_GAP = CONSTANTS.min_level_gap
#: severity at which a law's rate is stated and bounded (``rate_bounds``, first trials) [-]
MID_LIFE = 0.5


def regressor(h: NDArray[np.float64] | float, n_params: int) -> NDArray[np.float64]:
    """phi(h) of shape h.shape + (n_params,)."""
    h = np.asarray(h, dtype=float)
    return np.stack([h**j for j in range(n_params)], axis=-1)


def growth_rate(
    h: NDArray[np.float64], theta: NDArray[np.float64], min_rate: float
) -> NDArray[np.float64]:
    """g(h; theta) [1/flight], vectorised over particles.

    ``theta`` is either shape (p,) (one parameter vector for all particles) or (N, p) (one per
    particle, with ``h`` of shape (N,)). Horner evaluation, floored at ``min_rate``.
    """
    p = theta.shape[-1]
    out = np.empty_like(h)
    out[...] = theta[..., p - 1]
    for j in range(p - 2, -1, -1):
        out *= h
        out += theta[..., j]
    np.maximum(out, min_rate, out=out)
    return out


def rls_update(
    theta: NDArray[np.float64],
    cov: NDArray[np.float64],
    resid_var: float,
    phi: NDArray[np.float64],
    y: float,
    forgetting: float,
    max_trace: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64], float]:
    """One exponentially weighted RLS step (scalar output).

    Equations (lambda = forgetting)::

        e = y - phi . theta
        k = P phi / (lambda + phi' P phi)
        theta <- theta + k e
        P <- (P - k phi' P) / lambda,  then scaled down if trace(P) > max_trace (anti wind-up)
        s2 <- lambda s2 + (1 - lambda) e^2 / (1 + phi' P_old phi / lambda)

    Returns new (theta, P, s2); the inputs are not modified. One estimator of
    :func:`rls_update_batch`.
    """
    theta_new, cov_new, resid_var_new = rls_update_batch(
        theta[np.newaxis], cov[np.newaxis], resid_var, phi, y, forgetting, max_trace)
    return theta_new[0], cov_new[0], float(resid_var_new[0])


def rls_update_batch(
    theta: NDArray[np.float64],
    cov: NDArray[np.float64],
    resid_var: float,
    phi: NDArray[np.float64],
    y: float,
    forgetting: float,
    max_trace: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """:func:`rls_update` (its equations) of K estimators at once, theta (K, p) and cov
    (K, p, p), on one shared regressor and observation: the components of a mixture prior, in
    one set of array operations instead of K small ones. Returns (theta, P, s2), s2 of shape
    (K,)."""
    p_phi = cov @ phi
    denom = forgetting + p_phi @ phi
    gain = p_phi / denom[:, np.newaxis]
    err = y - theta @ phi
    theta_new = theta + gain * err[:, np.newaxis]
    cov_new = (cov - gain[:, :, np.newaxis] * p_phi[:, np.newaxis, :]) / forgetting
    cov_new = 0.5 * (cov_new + np.swapaxes(cov_new, 1, 2))
    tr = np.trace(cov_new, axis1=1, axis2=2)
    over = tr > max_trace
    if over.any():
        cov_new[over] *= (max_trace / tr[over])[:, np.newaxis, np.newaxis]
    # a-posteriori-normalised squared error: unbiased estimate of the output noise variance
    resid_var_new = forgetting * resid_var + (1.0 - forgetting) * err * err * forgetting / denom
    return theta_new, cov_new, resid_var_new


def exponential_law(theta: NDArray[np.float64], offset: float) -> NDArray[np.float64]:
    """Affine coefficients [r c, r] of dh/dk = r (h + c) from theta = (a, r), shape (2,) or
    (N, 2) (the intercept a plays no part in the growth rate)."""
    rate = theta[..., 1]
    return np.stack([rate * offset, rate], axis=-1)


def log_level_observation(h_obs: float, h_ref: float, sigma_h: float, offset: float
                          ) -> tuple[float, float]:
    """(y, sigma_y): ln|h + c| observed through a severity measurement h_obs with standard
    deviation sigma_h, linearised about the estimate h_ref (h_ref floored at 0, so a negative
    measurement near a healthy state stays finite). For a saturating law (c < -1), |h_ref + c|
    is kept at least ``MIN_LEVEL_GAP`` so that an estimate past the asymptote stays finite."""
    base = max(h_ref, 0.0) + offset
    if offset < 0.0:
        base = min(base, -MIN_LEVEL_GAP)
    return math.log(abs(base)) + (h_obs - h_ref) / base, sigma_h / abs(base)


def level_shift(dk: float) -> NDArray[np.float64]:
    """The log-level line's transition over ``dk`` units of the clock: (a, r) -> (a + r dk, r)."""
    return np.array([[1.0, dk], [0.0, 1.0]])


def level_measurement(
    theta: NDArray[np.float64],
    cov: NDArray[np.float64],
    dk: float,
    y: float,
    sigma_y: float,
    forgetting: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], float, float]:
    """The RLS step of the log-level line after ``dk`` units of the clock, before it is taken:
    (theta, P) moved to the latest flight (``a <- a + r dk``, ``P <- F P F'``), the whitened
    regressor [1 / sigma_y, 0] and observation y / sigma_y, and the forgetting ``lambda ** dk``
    (memory counted in the clock, whatever the spacing of the measurements). theta (p,) or
    (K, p) and cov (p, p) or (K, p, p): one line or the components of a mixture prior."""
    shift = level_shift(dk)
    theta = np.stack([theta[..., 0] + dk * theta[..., 1], theta[..., 1]], axis=-1)
    cov = shift @ cov @ shift.T
    phi = np.array([1.0 / sigma_y, 0.0])
    return theta, cov, phi, y / sigma_y, forgetting**dk


def level_rls_update(
    theta: NDArray[np.float64],
    cov: NDArray[np.float64],
    resid_var: float,
    dk: float,
    y: float,
    sigma_y: float,
    forgetting: float,
    max_trace: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64], float]:
    """One RLS step of the log-level line after ``dk`` units of the clock
    (:func:`level_measurement`, then :func:`rls_update`)."""
    theta, cov, phi, y_w, lam = level_measurement(theta, cov, dk, y, sigma_y, forgetting)
    return rls_update(theta, cov, resid_var, phi, y_w, lam, max_trace)


def bound_mid_rate(
    theta: NDArray[np.float64], bounds: tuple[float, float] | None
) -> NDArray[np.float64]:
    """Scale growth-rate coefficients (p,) or (N, p) so that the mid-life rate g(0.5) lies in
    ``bounds`` (the shape of the law is kept); a vector whose mid-life rate is not positive
    becomes the slowest plausible constant rate. ``None``: unchanged."""
    if bounds is None:
        return theta
    lo, hi = bounds
    mid = MID_LIFE ** np.arange(theta.shape[-1])
    if theta.ndim == 1:  # the filter's own law, once per update: no array temporaries
        rate = float(theta @ mid)
        if lo <= rate <= hi:
            return theta
        if rate <= 0:  # not a growth law: the slowest plausible constant rate
            out = np.zeros_like(theta)
            out[0] = lo
            return out
        return theta * (min(max(rate, lo), hi) / rate)
    rates = theta @ mid
    safe = np.where(rates > 0, rates, lo)
    out = theta * (np.clip(safe, lo, hi) / safe)[:, np.newaxis]
    out[rates <= 0] = np.eye(1, theta.shape[-1])[0] * lo
    return out
