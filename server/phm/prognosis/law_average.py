"""RUL from any health series by averaging degradation laws over their evidence.

The series is a severity (0 healthy, 1.0 = failure threshold) at times in the caller's unit.
Time is rescaled to the observed span, tau = (t - t_0) / (t_n - t_0), so every prior and the
horizon are in spans of the data seen so far, never per step. Each law is a linear model in a
basis of tau, some with one shape parameter on a grid (variable projection):

- ``constant``:    s = b0 + b1 tau                      (constant rate, Archard at steady load)
- ``affine``:      s = b0 + b1 (e^(k tau) - 1)/(e^k - 1) (rate affine in s: ds/dt = a + k s)
- ``exponential``: s = b1 e^(k (tau - 1))                (rate proportional to s)
- ``power``:       s = b0 + b1 tau^p                    (power-law growth)
- ``quadratic``:   s = b0 + b1 tau + b2 tau^2           (constant acceleration)
- ``onset``:       s = b0 + b1 max(tau - c, 0)^q, q 1 or 2 (healthy, then growth from c)

Every (law, shape) is a conjugate Bayesian regression (normal-inverse-gamma): the evidence
p(data | law, shape) is closed-form, the posterior over laws is the evidence averaged over
each law's shape grid (equal prior mass per law; within a law, the rate k of the affine and
exponential laws is log-uniform, prior mass 1/|k| per grid step, and the power law's
exponent is log-uniform by its log-spaced grid), and the RUL distribution is the mixture:
per sample, coefficients and noise drawn from the component's posterior, and the time at
which the noise-free curve first reaches 1. Priors are scaled by the data: coefficients
N(0, sigma^2 V0) with V0 = (``coef_scale`` / sigma_hat)^2 I, so their spread is
``coef_scale`` severity units whatever the noise; sigma^2 ~ IG centred on the robust noise
estimate sigma_hat of the prefix, worth ``noise_prior_weight`` samples.

``predictive_cdf`` is the mixture's closed-form predictive distribution of the mean of later
measurements, which the online guard of :mod:`.forecast` scores. Every law's shapes are fitted
at once (batched linear algebra). Numbers here are unit-free (severity and spans);
:mod:`.forecast` converts to the caller's units.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.special import gammaln, logsumexp, stdtr

from .constants import CONSTANTS
from .generic import estimate_noise_std

__all__ = ["LAW_NAMES", "LawAverageConfig", "LawMixture", "fit_laws", "predictive_cdf",
           "rul_samples"]

LAW_NAMES = ("constant", "affine", "exponential", "power", "quadratic", "onset")

# shape grids fine enough that the posterior over a shape is wider than a grid step on the
# prefixes the benchmark scores (a coarse grid biased the extrapolation)
_AFFINE_SHAPES = tuple(float(k) for k in np.linspace(-4.0, 8.0, 121) if abs(k) > 1e-9)
_EXP_SHAPES = tuple(float(k) for k in np.linspace(0.1, 8.0, 80))
_POWER_SHAPES = tuple(float(p) for p in np.geomspace(0.3, 6.0, 60))
# growth onset: flat, then growth from tau = c with exponent q (a fault that starts late)
_ONSET_SHAPES = tuple((float(c), q) for c in np.linspace(0.05, 0.95, 19) for q in (1.0, 2.0))


_RATE_PRIORS = ("log-uniform", "uniform")


@dataclass(frozen=True)
class LawAverageConfig:
    """Defaults of the law-averaging engine (unit-free: severity and observed spans).

    n_samples: RUL samples of the mixture. horizon_spans: the prediction stops this many
    observed spans after the last sample (beyond: "beyond horizon"). coef_scale: prior spread
    of each coefficient [severity]. noise_prior_weight: pseudo-samples of the noise prior.
    grid_points: points of the future-time grid on which crossings are found.
    memory_spans: samples are weighted exp(-(1 - tau) / memory_spans), so the fit is local
    to the recent past (no law holds over a whole life exactly; the weights' sum is the
    sample size the posterior believes); None weighs all samples equally. 0.25 was chosen
    among None, 1, 0.5, 0.25 and 0.15 on the tuning half of bench/bench_rul_calibration.py.
    rate_prior: prior over the rate k [1/span] of the affine and exponential laws within
    their grids. "log-uniform" (mass 1/|k|): a rate is a scale parameter (an inverse time),
    and the local fit cannot tell a gentle curve from a sharp knee, so a prior uniform in k
    puts half the exponential law's mass on rates above 4 per span and ends the forecasts
    too early (with it, on the tuning half 13 % of the truths lay above the 95th percentile, 4 %
    below the 5th, and the exponential law held 0.7 of the weight in those misses on
    average). "uniform": equal mass per grid step. Chosen on the tuning half of
    bench/bench_rul_calibration.py (50 % / 90 % coverage 0.50 / 0.87, CRA 0.78) against
    uniform (0.44 / 0.83 / 0.78), uniform with the likelihood tempered by the residuals'
    lag-1 autocorrelation, no exponential law, and log-uniform on the exponential law's rate
    only (docs/TUNING.md).

    The online guard (:mod:`.forecast`): guard_prefixes: how many earlier prefixes of the
    series forecast their own near future (0: no guard). guard_horizon: each forecasts
    K = max(3, round(guard_horizon x n)) samples ahead of its last one, n the series' sample
    count; the prefixes end K, 2K, ... samples before the last. guard_window: the share of
    those K samples, the last ones, whose mean is scored. guard_miss_rate: alpha, the
    forecast's interval is its central 1 - alpha. guard_gain: the widening's step
    [log(1 + RUL)] per scored forecast. 6 / 0.15 / 0.5 / 0.1 / 0.3 were chosen on the tuning
    half of bench/bench_rul_calibration.py (docs/TUNING.md).
    """

    n_samples: int = 4000
    horizon_spans: float = 20.0
    coef_scale: float = 2.0
    noise_prior_weight: float = 4.0
    grid_points: int = 1024
    memory_spans: float | None = 0.25
    rate_prior: str = "log-uniform"
    guard_prefixes: int = 6
    guard_horizon: float = 0.15
    guard_window: float = 0.5
    guard_miss_rate: float = 0.1
    guard_gain: float = 0.3

    def __post_init__(self) -> None:
        for name in ("n_samples", "grid_points"):
            value = getattr(self, name)
            if isinstance(value, bool) or not float(value).is_integer() or value < 2:
                raise ValueError(f"{name} must be a whole number >= 2, got {value!r}")
            object.__setattr__(self, name, int(value))
        if self.memory_spans is not None and not (math.isfinite(self.memory_spans)
                                                  and self.memory_spans > 0):
            raise ValueError(f"memory_spans must be finite and > 0, got {self.memory_spans!r}")
        if self.rate_prior not in _RATE_PRIORS:
            raise ValueError(f"rate_prior must be one of {_RATE_PRIORS}, got {self.rate_prior!r}")
        for name in ("horizon_spans", "coef_scale", "noise_prior_weight", "guard_horizon",
                     "guard_gain"):
            value = float(getattr(self, name))
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be finite and > 0, got {value!r}")
        value = self.guard_prefixes
        if isinstance(value, bool) or not float(value).is_integer() or value < 0:
            raise ValueError(f"guard_prefixes must be a whole number >= 0, got {value!r}")
        object.__setattr__(self, "guard_prefixes", int(value))
        if not 0.0 < float(self.guard_window) <= 1.0:
            raise ValueError(f"guard_window must be in (0, 1], got {self.guard_window!r}")
        if not 0.0 < float(self.guard_miss_rate) < 0.5:
            raise ValueError(f"guard_miss_rate must be in (0, 0.5), got "
                             f"{self.guard_miss_rate!r}")


def _basis(law: str, shape: Any, tau: NDArray[np.float64]) -> NDArray[np.float64]:
    """Design matrix (n, p) of one law at one shape."""
    one = np.ones_like(tau)
    if law == "constant":
        return np.column_stack([one, tau])
    if law == "quadratic":
        return np.column_stack([one, tau, tau * tau])
    if law == "affine":
        return np.column_stack([one, np.expm1(np.minimum(shape * tau, 700.0)) / math.expm1(shape)])
    if law == "exponential":
        return np.exp(np.minimum(shape * (tau - 1.0), 700.0))[:, None]
    if law == "power":
        return np.column_stack([one, np.power(tau, shape)])
    if law == "onset":
        c, q = shape
        return np.column_stack([one, np.maximum(tau - c, 0.0) ** q])
    raise ValueError(f"unknown law {law!r}")


def _components() -> list[tuple[str, Any]]:
    out: list[tuple[str, Any]] = [("constant", 0.0), ("quadratic", 0.0)]
    out += [("affine", k) for k in _AFFINE_SHAPES]
    out += [("exponential", k) for k in _EXP_SHAPES]
    out += [("power", p) for p in _POWER_SHAPES]
    out += [("onset", cq) for cq in _ONSET_SHAPES]
    return out


COMPONENTS = tuple(_components())


def _log_prior(rate_prior: str) -> NDArray[np.float64]:
    """Log prior mass of each component: 1/6 per law, shared among its shapes (in
    proportion to 1/|k| for the affine and exponential rates when log-uniform)."""
    raw = np.array([-math.log(abs(k)) if rate_prior == "log-uniform"
                    and law in ("affine", "exponential") else 0.0 for law, k in COMPONENTS])
    out = np.empty_like(raw)
    for name in LAW_NAMES:
        mask = np.array([law == name for law, _ in COMPONENTS])
        out[mask] = raw[mask] - logsumexp(raw[mask])
    return out


_LOG_PRIORS = {name: _log_prior(name) for name in _RATE_PRIORS}


@dataclass(frozen=True)
class _Posterior:
    """Normal-inverse-gamma posterior of one (law, shape)."""

    law: str
    shape: Any  # the law's shape parameter (a float, or (c, q) for onset)
    mean: NDArray[np.float64]
    cov_unit: NDArray[np.float64]  # covariance of the coefficients / sigma^2
    a: float
    b: float
    log_evidence: float


@dataclass(frozen=True)
class LawMixture:
    """Posterior over laws and shapes after a prefix of the series."""

    components: tuple[_Posterior, ...]
    weights: NDArray[np.float64]  # posterior probability of each component
    noise_std: float  # robust noise estimate of the prefix [severity]

    @property
    def law_weights(self) -> dict[str, float]:
        """Posterior probability of each law (its shapes summed)."""
        out = dict.fromkeys(LAW_NAMES, 0.0)
        for comp, w in zip(self.components, self.weights, strict=True):
            out[comp.law] += float(w)
        return out


def robust_noise_std(severity: NDArray[np.float64]) -> float:
    """The prefix's white-noise estimate (:func:`.generic.estimate_noise_std`), or the
    short-series default below 4 samples."""
    if severity.size < 4:
        return CONSTANTS.short_series_noise
    return estimate_noise_std(severity)


def _basis_stack(law: str, shapes: tuple[Any, ...], tau: NDArray[np.float64]
                 ) -> NDArray[np.float64]:
    """Design matrices (S, n, p) of one law at each of its S shapes (:func:`_basis` stacked,
    computed at once)."""
    one = np.ones((len(shapes), tau.size))
    if law in ("constant", "quadratic"):
        return np.stack([_basis(law, shape, tau) for shape in shapes])
    if law == "onset":
        c = np.array([cq[0] for cq in shapes])[:, None]
        q = np.array([cq[1] for cq in shapes])[:, None]
        return np.stack([one, np.maximum(tau[None, :] - c, 0.0) ** q], axis=2)
    k = np.array(shapes, dtype=float)[:, None]
    if law == "affine":
        return np.stack([one, np.expm1(np.minimum(k * tau[None, :], 700.0)) / np.expm1(k)],
                        axis=2)
    if law == "exponential":
        return np.exp(np.minimum(k * (tau[None, :] - 1.0), 700.0))[:, :, None]
    if law == "power":
        return np.stack([one, np.power(tau[None, :], k)], axis=2)
    raise ValueError(f"unknown law {law!r}")


@dataclass(frozen=True)
class _LawFit:
    """Normal-inverse-gamma posteriors of one law at each of its shapes (arrays over shapes)."""

    law: str
    shapes: tuple[Any, ...]
    mean: NDArray[np.float64]  # (S, p)
    cov_unit: NDArray[np.float64]  # (S, p, p): covariance of the coefficients / sigma^2
    a: NDArray[np.float64]  # (S,)
    b: NDArray[np.float64]  # (S,)
    log_evidence: NDArray[np.float64]  # (S,)


def _fit_law(law: str, shapes: tuple[Any, ...], tau: NDArray[np.float64],
             y: NDArray[np.float64], w: NDArray[np.float64], sigma_hat: float,
             cfg: LawAverageConfig) -> _LawFit:
    """Every shape of ``law`` fitted at once (one batched linear algebra call per step)."""
    x = _basis_stack(law, shapes, tau)  # (S, n, p)
    p = x.shape[2]
    xw = x * w[None, :, None]
    prior_prec = (sigma_hat / cfg.coef_scale) ** 2  # V0^-1 = (sigma_hat / coef_scale)^2 I
    a0 = cfg.noise_prior_weight / 2.0
    b0 = a0 * sigma_hat ** 2
    prec = np.einsum("snp,snq->spq", xw, x) + prior_prec * np.eye(p)
    chol = np.linalg.cholesky(prec)
    rhs = np.einsum("snp,n->sp", xw, y)
    mean = np.linalg.solve(prec, rhs[:, :, None])[:, :, 0]
    n = float(w.sum())
    a = a0 + n / 2.0
    b = b0 + 0.5 * (float(y @ (w * y)) - np.einsum("sp,spq,sq->s", mean, prec, mean))
    b = np.maximum(b, 1e-300)
    log_det_prec = 2.0 * np.sum(np.log(np.diagonal(chol, axis1=1, axis2=2)), axis=1)
    log_evidence = (0.5 * (p * math.log(prior_prec) - log_det_prec) + a0 * math.log(b0)
                    - a * np.log(b) + float(gammaln(a) - gammaln(a0))
                    - 0.5 * n * math.log(2.0 * math.pi))
    return _LawFit(law, shapes, mean, np.linalg.inv(prec), np.full(len(shapes), a), b,
                   log_evidence)


#: the laws in ``COMPONENTS`` order, each with its shapes
_SHAPES_BY_LAW = {name: tuple(k for law, k in COMPONENTS if law == name)
                  for name in dict.fromkeys(law for law, _ in COMPONENTS)}


def _fit_all(tau: NDArray[np.float64], severity: NDArray[np.float64], cfg: LawAverageConfig
             ) -> tuple[list[_LawFit], NDArray[np.float64], float]:
    """Every (law, shape) fitted to the prefix (in ``COMPONENTS`` order), the posterior
    weight of each and the noise estimate."""
    sigma_hat = robust_noise_std(severity)
    w = (np.ones_like(tau) if cfg.memory_spans is None
         else np.exp(-(1.0 - tau) / cfg.memory_spans))
    fits = [_fit_law(name, shapes, tau, severity, w, sigma_hat, cfg)
            for name, shapes in _SHAPES_BY_LAW.items()]
    log_w = _LOG_PRIORS[cfg.rate_prior] + np.concatenate([f.log_evidence for f in fits])
    return fits, np.exp(log_w - logsumexp(log_w)), sigma_hat


def fit_laws(tau: NDArray[np.float64], severity: NDArray[np.float64],
             cfg: LawAverageConfig) -> LawMixture:
    """Every (law, shape) fitted to the prefix, weighted by its evidence times its prior
    (equal mass per law, shared among its shapes as ``cfg.rate_prior`` says)."""
    fits, weights, sigma_hat = _fit_all(tau, severity, cfg)
    comps = tuple(_Posterior(f.law, shape, f.mean[i], f.cov_unit[i], float(f.a[i]),
                             float(f.b[i]), float(f.log_evidence[i]))
                  for f in fits for i, shape in enumerate(f.shapes))
    return LawMixture(comps, weights, sigma_hat)


def predictive_cdf(tau: NDArray[np.float64], severity: NDArray[np.float64],
                   cfg: LawAverageConfig, future_tau: NDArray[np.float64],
                   future_mean: float) -> float:
    """P(the mean of measurements at ``future_tau`` <= ``future_mean``) under the mixture
    fitted to (``tau``, ``severity``). Per component the closed-form Student-t predictive:
    2a degrees of freedom, location phi_bar' beta and scale^2 (b/a)(1/m + phi_bar' V
    phi_bar), beta the coefficients' posterior mean, V their covariance / sigma^2, phi_bar the
    mean basis over the m future times (each sample's noise that of a sample of weight 1, the
    newest's); summed with the posterior weights. Deterministic; no draw."""
    fits, weights, _ = _fit_all(tau, severity, cfg)
    m = float(future_tau.size)
    cdf = 0.0
    start = 0
    for f in fits:
        phi = _basis_stack(f.law, f.shapes, future_tau).mean(axis=1)  # (S, p)
        mu = np.einsum("sp,sp->s", phi, f.mean)
        var = (f.b / f.a) * (1.0 / m + np.einsum("sp,spq,sq->s", phi, f.cov_unit, phi))
        z = (future_mean - mu) / np.sqrt(var)
        cdf += float(weights[start:start + f.a.size] @ stdtr(2.0 * f.a, z))
        start += f.a.size
    return cdf


def _future_grid(cfg: LawAverageConfig) -> NDArray[np.float64]:
    """Future times tau in (1, 1 + horizon], dense near the present (quadratic spacing)."""
    u = np.arange(1, cfg.grid_points + 1, dtype=float) / cfg.grid_points
    return 1.0 + cfg.horizon_spans * u * u


def rul_samples(mixture: LawMixture, cfg: LawAverageConfig,
                rng: np.random.Generator) -> NDArray[np.float64]:
    """RUL samples [observed spans] of the mixture: per sample a component by its weight,
    coefficients and noise from its posterior, the first time the curve reaches 1 (0 if it
    already has at the last sample, inf beyond the horizon)."""
    counts = rng.multinomial(cfg.n_samples, mixture.weights)
    grid = _future_grid(cfg)
    now = np.array([1.0])
    out = []
    for comp, m in zip(mixture.components, counts, strict=True):
        if m == 0:
            continue
        sigma2 = comp.b / rng.gamma(comp.a, 1.0, m)
        z = rng.multivariate_normal(np.zeros(comp.mean.size), comp.cov_unit, m,
                                    method="cholesky")
        beta = comp.mean + z * np.sqrt(sigma2)[:, None]
        path = beta @ _basis(comp.law, comp.shape, grid).T  # (m, G)
        current = (beta @ _basis(comp.law, comp.shape, now).T)[:, 0]
        out.append(_first_crossing(path, current, grid))
    return np.concatenate(out)


def _first_crossing(path: NDArray[np.float64], current: NDArray[np.float64],
                    grid: NDArray[np.float64]) -> NDArray[np.float64]:
    above = path >= 1.0
    hit = above.any(axis=1)
    j = np.argmax(above, axis=1)
    rul = np.full(path.shape[0], np.inf)
    prev_t = np.where(j > 0, grid[np.maximum(j - 1, 0)], 1.0)
    rows = np.arange(path.shape[0])
    prev_v = np.where(j > 0, path[rows, np.maximum(j - 1, 0)], current)
    this_v = path[rows, j]
    frac = np.clip((1.0 - prev_v) / np.where(this_v > prev_v, this_v - prev_v, 1.0), 0.0, 1.0)
    cross = prev_t + frac * (grid[j] - prev_t)
    rul[hit] = cross[hit] - 1.0
    rul[current >= 1.0] = 0.0
    return rul
