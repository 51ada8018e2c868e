"""Particle filter on fault severity with an RLS-tuned degradation model.

Roles (after progpy): the *degradation model* (:mod:`.degradation`) moves severity forward, the
*measurement model* (:class:`.MeasurementModel`) scores a feature value, the *filter*
(:meth:`ParticleFilterPrognoser.update`) fuses one flight's feature, and the *predictor*
(:meth:`ParticleFilterPrognoser.predict`, :mod:`.predictor`) rolls every particle to the threshold.

One update at flight k (dk = k - k_prev flights since the previous update)::

    1. propagate   h_i <- max(h_i + dk g(h_i; theta) + q sqrt(dk) w_i, 0)
    2. weight      log w_i <- log w_i - (z - h(h_i))^2 / (2 sigma_v(h_i)^2) - log sigma_v(h_i),
                   max subtracted, normalised (sigma_v grows with severity: .measurement)
    3. resample    systematic, only when ESS = 1 / sum w_i^2 < resample_threshold * N
    4. tune        one RLS step on the measurement the law poses (:mod:`.laws`): y =
                   (h_hat[k] - h_hat[k_prev]) / dk against phi(h_hat[k_prev]), or for the
                   "exponential" law the log-level ln(h + c) (see .degradation)

The first measurement initialises the cloud around the inverted measurement,
h_i = h^-1(z) + sigma_v / |h'| w_i, instead of weighting the prior.

The state (:class:`PrognoserState`) is immutable: ``update`` returns a new one. It holds
everything that changes between flights, including the random generator state, so that storing
it as JSON between flights and restoring it gives bit-identical subsequent outputs. ``predict``
does not advance the state's generator: it draws from an independent stream jumped from it, so
predicting is repeatable and does not perturb the next update.

Units: severity normalised (failure threshold 1.0), time in flights, flight hours optional.
"""

from __future__ import annotations

import hashlib
import json
import math
import threading
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .calibration import widen
from .config import PrognoserConfig
from .degradation import bound_mid_rate, growth_rate, rls_update
from .guard import GuardState, forecast, score
from .hypotheses import leading_hypothesis
from .measurement import MeasurementModel
from .mixture import BandEvidence, RateMixture
from .predictor import RulDistribution, propagate_to_threshold, summarise_rul

__all__ = [
    "ParticleFilterPrognoser",
    "PrognoserState",
    "StaleStateError",
    "effective_sample_size",
    "systematic_resample",
]

_STATE_VERSION = 1


class StaleStateError(ValueError):
    """A stored filter state that belongs to another model version: another state format,
    config or measurement model, or particle count. The caller restarts the filter; every
    other ``ValueError`` (a non-monotone flight index, a non-finite value) is a real error."""


def effective_sample_size(weights: NDArray[np.float64]) -> float:
    """ESS = 1 / sum(w_i^2) for normalised weights, in [1, N]."""
    return float(1.0 / np.dot(weights, weights))


def systematic_resample(weights: NDArray[np.float64], rng: np.random.Generator) -> NDArray[np.intp]:
    """Systematic resampling: one uniform draw u ~ U[0, 1/N), positions u + j/N (Kitagawa 1996).

    Returns the indices of the selected particles, shape (N,), sorted.
    """
    n = weights.size
    positions = (rng.random() + np.arange(n)) / n
    cdf = np.cumsum(weights)
    cdf[-1] = 1.0  # guard against round-off
    return np.searchsorted(cdf, positions, side="right")


def _digest(config: PrognoserConfig, model: MeasurementModel) -> str:
    text = config.to_json() + model.to_json()
    return hashlib.sha256(text.encode()).hexdigest()[:16]


@dataclass(frozen=True)
class PrognoserState:
    """Everything the filter carries from one flight to the next.

    Attributes
    ----------
    severity:
        Particle severities [-], shape (N,).
    log_weights:
        Normalised log-weights [-], shape (N,) (logsumexp = 0).
    theta, cov, resid_var:
        RLS parameters (p,), normalised covariance (p, p), residual variance [1/flight^2];
        with a mixture rate prior, the mixture's mean and covariance.
    rng_state:
        ``Generator.bit_generator.state`` (a dict) of the filter's generator.
    flight_index:
        Flight of the last update (None before the first).
    last_estimate:
        Weighted mean severity after the last update (None before the first) [-].
    n_updates, n_resamples:
        Counters [-].
    last_ess:
        Effective sample size after weighting at the last update, before any resampling [-].
    resampled:
        Whether the last update resampled.
    hours_total, hours_flights:
        Sum of the flight hours given and the number of flights that had them.
    config_digest:
        Short hash of the config and measurement model the state belongs to.
    mixture:
        The components of a mixture rate prior (a bank of ``PrognoserConfig.rate_hypotheses``
        or ``rate_prior_tail`` > 0), else None.
    guard:
        The online guard's forecasts and widening (``PrognoserConfig.guard_horizon`` > 0,
        :mod:`.guard`); else None.
    """

    severity: NDArray[np.float64]
    log_weights: NDArray[np.float64]
    theta: NDArray[np.float64]
    cov: NDArray[np.float64]
    resid_var: float
    rng_state: Mapping[str, Any]
    config_digest: str
    flight_index: int | None = None
    last_estimate: float | None = None
    n_updates: int = 0
    n_resamples: int = 0
    last_ess: float = math.nan
    resampled: bool = False
    hours_total: float = 0.0
    hours_flights: int = 0
    mixture: RateMixture | None = None
    guard: GuardState | None = None
    version: int = field(default=_STATE_VERSION)

    @property
    def weights(self) -> NDArray[np.float64]:
        """Normalised particle weights, shape (N,)."""
        w = np.exp(self.log_weights)
        return w / w.sum()

    @property
    def severity_mean(self) -> float:
        return float(np.dot(self.weights, self.severity))

    @property
    def hours_per_flight(self) -> float | None:
        return self.hours_total / self.hours_flights if self.hours_flights else None

    # -- persistence ------------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        out = {
            "version": _STATE_VERSION,
            "kind": "pf_prognoser_state",
            "config_digest": self.config_digest,
            "severity": self.severity.tolist(),
            "log_weights": self.log_weights.tolist(),
            "theta": self.theta.tolist(),
            "cov": self.cov.tolist(),
            "resid_var": self.resid_var,
            "rng_state": _encode_ints(self.rng_state),
            "flight_index": self.flight_index,
            "last_estimate": self.last_estimate,
            "n_updates": self.n_updates,
            "n_resamples": self.n_resamples,
            "last_ess": None if math.isnan(self.last_ess) else self.last_ess,
            "resampled": self.resampled,
            "hours_total": self.hours_total,
            "hours_flights": self.hours_flights,
        }
        if self.mixture is not None:  # absent otherwise: states without one read as before
            out["mixture"] = self.mixture.to_dict()
        if self.guard is not None:
            out["guard"] = self.guard.to_dict()
        return out

    def to_json(self) -> str:
        """JSON text; floats are written with repr, so ``from_json`` restores them bit-exactly."""
        return json.dumps(self.to_dict(), allow_nan=False)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> PrognoserState:
        if data.get("version") != _STATE_VERSION or data.get("kind") != "pf_prognoser_state":
            raise StaleStateError(
                f"unsupported prognoser state {data.get('kind')!r} v{data.get('version')!r}"
            )
        severity = np.asarray(data["severity"], dtype=float)
        log_weights = np.asarray(data["log_weights"], dtype=float)
        if severity.ndim != 1 or severity.shape != log_weights.shape:
            raise ValueError("severity and log_weights must be 1-D of equal length")
        if data.get("log_rates") is not None:
            raise StaleStateError("a joint state-parameter filter's state: that filter was "
                                  "retired (docs/PROGNOSIS.md); the unit's filter restarts")
        return cls(
            severity=severity,
            log_weights=log_weights,
            theta=np.asarray(data["theta"], dtype=float),
            cov=np.asarray(data["cov"], dtype=float),
            resid_var=float(data["resid_var"]),
            rng_state=_decode_ints(data["rng_state"]),
            config_digest=str(data["config_digest"]),
            flight_index=data["flight_index"],
            last_estimate=data["last_estimate"],
            n_updates=int(data["n_updates"]),
            n_resamples=int(data["n_resamples"]),
            last_ess=math.nan if data["last_ess"] is None else float(data["last_ess"]),
            resampled=bool(data["resampled"]),
            hours_total=float(data["hours_total"]),
            hours_flights=int(data["hours_flights"]),
            mixture=None if data.get("mixture") is None
            else RateMixture.from_dict(data["mixture"]),
            guard=None if data.get("guard") is None else GuardState.from_dict(data["guard"]),
        )

    @classmethod
    def from_json(cls, text: str) -> PrognoserState:
        return cls.from_dict(json.loads(text))

    def to_npz(self, path: str) -> None:
        """Write arrays natively and the rest as JSON text inside one ``.npz`` (no pickle)."""
        meta = self.to_dict()
        arrays = {
            k: np.asarray(meta.pop(k), dtype=float)
            for k in ("severity", "log_weights", "theta", "cov") if k in meta
        }
        # numpy's stub reads **arrays as possibly its allow_pickle flag; the keys are fixed above
        np.savez(path, meta=np.array(json.dumps(meta)), **arrays)  # type: ignore[arg-type]

    @classmethod
    def from_npz(cls, path: str) -> PrognoserState:
        with np.load(path, allow_pickle=False) as npz:
            meta = json.loads(str(npz["meta"]))
            for k in ("severity", "log_weights", "theta", "cov", "log_rates"):
                if k in npz:  # log_rates: a retired joint filter's, refused by from_dict
                    meta[k] = npz[k]
        return cls.from_dict(meta)


def _encode_ints(obj: Any) -> Any:
    """Big ints (PCG64 state is 128-bit) as tagged decimal strings, safe for any JSON reader."""
    if isinstance(obj, dict):
        return {k: _encode_ints(v) for k, v in obj.items()}
    if isinstance(obj, bool):
        return obj
    if isinstance(obj, int):
        return {"int": str(obj)}
    return obj


def _decode_ints(obj: Any) -> Any:
    if isinstance(obj, dict):
        if set(obj) == {"int"}:
            return int(obj["int"])
        return {k: _decode_ints(v) for k, v in obj.items()}
    return obj


_BIT_GENERATORS = threading.local()


def _generator(rng_state: Mapping[str, Any]) -> np.random.Generator:
    """A generator at ``rng_state``. Its bit generator is reused per thread (a new one seeds
    itself from the OS, 10 us, the update's largest fixed cost), so the generator is valid
    until the next call in the same thread; ``update`` uses it and stores its state before
    returning."""
    name = rng_state["bit_generator"]
    bit_gen = getattr(_BIT_GENERATORS, name, None)
    if bit_gen is None:
        bit_gen = getattr(np.random, name)(0)
        setattr(_BIT_GENERATORS, name, bit_gen)
    bit_gen.state = rng_state
    return np.random.Generator(bit_gen)


class ParticleFilterPrognoser:
    """Particle-filter prognoser for one fault mode of one actuator.

    The object holds only the (immutable) config and measurement model; all per-flight data live
    in :class:`PrognoserState`, so one prognoser serves every actuator with that fault mode.

    Examples
    --------
    >>> pf = ParticleFilterPrognoser(config, model)              # doctest: +SKIP
    >>> state = pf.initial_state(config, model, rng_seed=7)      # doctest: +SKIP
    >>> state = pf.update(state, feature_value, flight_index=42) # doctest: +SKIP
    >>> dist = pf.predict(state)                                 # doctest: +SKIP
    """

    def __init__(self, config: PrognoserConfig, measurement_model: MeasurementModel) -> None:
        if not isinstance(config, PrognoserConfig):
            raise ValueError("config must be a PrognoserConfig")
        if not isinstance(measurement_model, MeasurementModel):
            raise ValueError("measurement_model must be a MeasurementModel")
        self.config = config
        self.measurement_model = measurement_model
        self.law = config.law
        self.digest = _digest(config, measurement_model)
        self._prior_mixture = self.law.prior_mixture(config) if config.rate_mixture else None

    @classmethod
    def initial_state(
        cls,
        config: PrognoserConfig,
        measurement_model: MeasurementModel,
        rng_seed: int | np.random.SeedSequence,
    ) -> PrognoserState:
        """Prior state: severity uniform on [0, initial_severity_max], first-trial RLS params."""
        if isinstance(rng_seed, bool) or not isinstance(rng_seed, int | np.random.SeedSequence):
            raise ValueError("rng_seed must be an int or a SeedSequence")
        rng = np.random.Generator(np.random.PCG64(rng_seed))
        n = config.n_particles
        severity = rng.uniform(0.0, config.initial_severity_max, n)
        law = config.law
        cov, resid_var = law.prior(config)
        theta = np.asarray(config.theta0, dtype=float)
        mixture = law.prior_mixture(config) if config.rate_mixture else None
        if mixture is not None:
            theta, cov = mixture.moments()
        return PrognoserState(
            guard=GuardState() if config.guard_horizon > 0 else None,
            severity=severity,
            log_weights=np.full(n, -math.log(n)),
            theta=theta,
            cov=cov,
            resid_var=resid_var,
            mixture=mixture,
            rng_state=rng.bit_generator.state,
            config_digest=_digest(config, measurement_model),
        )

    def _check(self, state: PrognoserState) -> None:
        if state.config_digest != self.digest:
            raise StaleStateError("state belongs to another config or measurement model")
        if state.severity.size != self.config.n_particles:
            raise StaleStateError("state has the wrong number of particles")

    def update(
        self,
        state: PrognoserState,
        feature_value: float,
        flight_index: int,
        *,
        flight_hours: float | None = None,
        stress: float | None = None,
    ) -> PrognoserState:
        """Fuse the feature of flight ``flight_index`` and return the new state.

        ``flight_index`` must increase strictly between updates; gaps (skipped flights) are
        propagated with dk > 1. ``flight_hours`` is the duration of this flight [h].
        ``stress`` is the ageing time since the previous update in the degradation law's
        clock (:mod:`server.phm.season`); default the number of flights, dk.
        """
        self._check(state)
        z = float(feature_value)
        if not math.isfinite(z):
            raise ValueError("feature_value must be finite")
        k = int(flight_index)
        if state.flight_index is not None and k <= state.flight_index:
            raise ValueError(f"flight_index must increase: {k} after {state.flight_index}")
        cfg = self.config
        mm = self.measurement_model
        rng = _generator(state.rng_state)
        n = cfg.n_particles
        hours_total, hours_flights = state.hours_total, state.hours_flights
        if flight_hours is not None:
            if not (math.isfinite(flight_hours) and flight_hours >= 0):
                raise ValueError("flight_hours must be finite and >= 0")
            hours_total += float(flight_hours)
            hours_flights += 1

        if state.flight_index is None:
            # first measurement: initialise around the inverted measurement
            s0 = mm.invert_one(z)
            spread = mm.severity_noise(s0)
            h = np.maximum(s0 + spread * rng.standard_normal(n), 0.0)
            log_w = np.full(n, -math.log(n))
            estimate = float(h.mean())
            theta, cov = self.law.first_measurement(state.theta, state.cov, s0, spread)
            mixture = state.mixture
            if mixture is not None:
                firsts = [self.law.first_measurement(t, c, s0, spread)
                          for t, c in zip(mixture.theta, mixture.cov, strict=True)]
                thetas = np.array([t for t, _ in firsts])
                covs = np.array([c for _, c in firsts])
                mixture = RateMixture(thetas, covs, mixture.log_weights,
                                      BandEvidence.start(thetas, covs)
                                      if self.config.rate_weighting == "evidence" else None)
                theta, cov = mixture.moments()
            guard = self._forecast(state.guard, k, h, theta, np.full(n, 1.0 / n), rng)
            return replace(
                state,
                severity=h,
                log_weights=log_w,
                theta=theta,
                cov=cov,
                mixture=mixture,
                guard=guard,
                rng_state=rng.bit_generator.state,
                flight_index=k,
                last_estimate=estimate,
                n_updates=state.n_updates + 1,
                last_ess=float(n),
                resampled=False,
                hours_total=hours_total,
                hours_flights=hours_flights,
            )

        dk = float(k - state.flight_index)
        if stress is not None:
            if not (math.isfinite(stress) and stress > 0):
                raise ValueError("stress must be finite and > 0")
            dk = float(stress)  # from here on, the law's clock
        guard = None if state.guard is None else score(state.guard, k, mm.invert_one(z), cfg)
        # 1. propagate
        # the law is bounded where it is used (propagation, prediction), not inside the RLS:
        # a rescaled RLS estimate feeds back into the regression and drifts
        h = state.severity + dk * growth_rate(
            state.severity, self._law(state.theta), cfg.min_rate)
        h += (cfg.process_noise_std * math.sqrt(dk)) * rng.standard_normal(n)
        np.maximum(h, 0.0, out=h)
        # 2. weight (log domain, max subtracted before exponentiating)
        log_w = state.log_weights + mm.log_likelihood(z, h)
        log_w -= log_w.max()
        w = np.exp(log_w)
        total = w.sum()
        w /= total
        log_w -= math.log(total)
        ess = effective_sample_size(w)
        estimate = float(np.dot(w, h))
        # 3. resample only when ESS < threshold * N
        resampled = ess < cfg.resample_threshold * n
        if resampled:
            idx = systematic_resample(w, rng)
            h = h[idx]
            log_w = np.full(n, -math.log(n))
            w = np.full(n, 1.0 / n)
        # 4. tune the degradation model: one RLS step on the law's measurement
        theta, cov, resid_var, mixture = self._tune(state, estimate, z, dk)
        guard = self._forecast(guard, k, h, theta, w, rng,
                               clock_rate=dk / (k - state.flight_index))
        return PrognoserState(
            severity=h,
            log_weights=log_w,
            theta=theta,
            cov=cov,
            resid_var=resid_var,
            rng_state=rng.bit_generator.state,
            config_digest=state.config_digest,
            flight_index=k,
            last_estimate=estimate,
            n_updates=state.n_updates + 1,
            n_resamples=state.n_resamples + int(resampled),
            last_ess=ess,
            resampled=bool(resampled),
            hours_total=hours_total,
            hours_flights=hours_flights,
            mixture=mixture,
            guard=guard,
        )

    def _rate_ratio(self, state: PrognoserState) -> float:
        """The RLS estimate's rate over its prior's centre (the calibration layer's group key
        without a bank of hypotheses) for the exponential law; nan for the polynomial laws,
        whose rate depends on the severity."""
        if self.config.rate_basis != "exponential":
            return math.nan
        ratio = float(state.theta[1]) / self.config.theta0[1]
        return ratio if ratio > 0 else math.nan

    def _forecast(self, guard: GuardState | None, flight: int, severity: NDArray[np.float64],
                  theta: NDArray[np.float64], weights: NDArray[np.float64],
                  rng: np.random.Generator, clock_rate: float = 1.0) -> GuardState | None:
        """The guard with this update's feature forecast added (None without a guard)."""
        if guard is None:
            return None
        return forecast(guard, flight, severity, self._law(theta), weights,
                        self.measurement_model, self.config, rng, clock_rate)

    def _tune(self, state: PrognoserState, estimate: float, z: float, dk: float
              ) -> tuple[NDArray[np.float64], NDArray[np.float64], float, RateMixture | None]:
        """One RLS step on the law's measurement, per component of a mixture prior (then
        theta and cov are the mixture's moments): (theta, cov, resid_var, mixture)."""
        cfg, mm = self.config, self.measurement_model
        if state.mixture is None or self._prior_mixture is None:
            step = self.law.rls_measurement(state, estimate, z, dk, mm, cfg)
            theta, cov, resid_var = rls_update(step.theta, step.cov, state.resid_var, step.phi,
                                               step.y, step.forgetting, cfg.rls_max_trace)
            return theta, cov, resid_var, None
        mix = state.mixture
        # the components share the law's observation: one batched RLS step for all of them
        step = self.law.rls_measurement(replace(state, theta=mix.theta, cov=mix.cov), estimate,
                                        z, dk, mm, cfg)
        mix, resid_var = mix.update(step, state.resid_var, cfg.rls_max_trace,
                                    self._prior_mixture.log_weights, dk)
        theta, cov = mix.moments()
        return theta, cov, resid_var, mix

    def parameter_samples(
        self, state: PrognoserState, rng: np.random.Generator
    ) -> NDArray[np.float64]:
        """One vector of growth-rate coefficients per particle, (N, p), drawn from the RLS
        estimate and its covariance by the law (:meth:`.laws.DegradationLaw.parameter_samples`;
        polynomial laws: theta_i ~ N(theta, c s2 P), with ``config.monotone_rate`` the
        severity-dependent terms clipped at 0 and the constant term compensating, so that the
        rate at the current severity is unchanged).
        """
        return self.law.parameter_samples(state, rng, self.config)

    def _law(self, theta: NDArray[np.float64]) -> NDArray[np.float64]:
        """Growth-rate coefficients (of :func:`.growth_rate`) of RLS parameters (p,) or (N, p),
        kept within ``config.rate_bounds``."""
        return bound_mid_rate(self.law.coefficients(theta), self.config.rate_bounds)

    def predict(self, state: PrognoserState, *, threshold: float = 1.0,
                at_flight: int | None = None,
                stress_curve: NDArray[np.float64] | None = None) -> RulDistribution:
        """Long-term prediction: RUL distribution from the state (does not modify it).

        ``at_flight`` (>= the state's flight) asks for the RUL as seen at a later flight that
        brought no measurement: every particle's trajectory goes on from the last update,
        so its RUL is shortened by the flights since (0 if it would have reached the
        threshold already). Without it the RUL counts from the last update.

        ``stress_curve`` is the law's clock over the coming flights: cumulative stress from
        the last update's flight to each of the next flights, increasing, starting at 0
        (:meth:`server.phm.season.StressClock.curve`). The particles are propagated in stress
        and their crossing times mapped back to flights; a particle that needs more stress
        than the curve holds is beyond the horizon. Default: one unit per flight.
        """
        self._check(state)
        bit_gen = getattr(np.random, state.rng_state["bit_generator"])()
        bit_gen.state = state.rng_state
        rng = np.random.Generator(bit_gen.jumped())
        theta = self.parameter_samples(state, rng)
        if stress_curve is None:
            rul = propagate_to_threshold(state.severity, theta, self.config, rng,
                                         threshold=threshold)
        else:
            curve = np.asarray(stress_curve, dtype=float)
            if curve.ndim != 1 or curve.size < 2 or curve[0] != 0.0 or \
                    not np.all(np.diff(curve) > 0) or not np.isfinite(curve[-1]):
                raise ValueError("stress_curve must start at 0 and increase strictly")
            need = propagate_to_threshold(state.severity, theta, self.config, rng,
                                          threshold=threshold, horizon=float(curve[-1]))
            rul = np.full_like(need, np.inf)
            ok = np.isfinite(need)
            rul[ok] = np.interp(need[ok], curve, np.arange(curve.size, dtype=float))
        flight = state.flight_index
        if at_flight is not None and flight is not None:
            elapsed = int(at_flight) - flight
            if elapsed < 0:
                raise ValueError(f"at_flight {at_flight} is before the last update {flight}")
            rul = np.maximum(rul - elapsed, 0.0)
            flight = int(at_flight)
        dist = summarise_rul(
            rul,
            state.weights,
            state.severity,
            self.config,
            flight_index=flight,
            hours_per_flight=state.hours_per_flight,
        )
        ratio = self._rate_ratio(state)
        if math.isfinite(ratio):
            dist = replace(dist, rate_ratio=ratio)
        if self.config.rate_hypotheses and state.mixture is not None:
            dist = replace(dist, hypothesis=leading_hypothesis(self.config.rate_hypotheses,
                                                               state.mixture.weights))
        guard = state.guard
        if guard is not None and (guard.widening_fast > 0.0 or guard.widening_slow > 0.0):
            dist = replace(widen(dist, guard.margins()), adjustment={
                "guard_widening": [guard.widening_fast, guard.widening_slow]})
        return dist
