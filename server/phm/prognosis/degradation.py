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

All functions are pure and work on small numpy arrays; nothing here is random.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["growth_rate", "regressor", "rls_update"]


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

    Returns new (theta, P, s2); the inputs are not modified.
    """
    p_phi = cov @ phi
    denom = forgetting + float(phi @ p_phi)
    gain = p_phi / denom
    err = y - float(phi @ theta)
    theta_new = theta + gain * err
    cov_new = (cov - np.outer(gain, p_phi)) / forgetting
    cov_new = 0.5 * (cov_new + cov_new.T)
    tr = float(np.trace(cov_new))
    if tr > max_trace:
        cov_new *= max_trace / tr
    # a-posteriori-normalised squared error: unbiased estimate of the output noise variance
    resid_var_new = forgetting * resid_var + (1.0 - forgetting) * err * err * forgetting / denom
    return theta_new, cov_new, resid_var_new
