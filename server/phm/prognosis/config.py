"""Configuration of the particle-filter prognoser.

Conventions
-----------
- Severity ``h`` is normalised so that the failure threshold is ``1.0`` (dimensionless); a healthy
  component has ``h = 0``.
- Time is counted in flights (``k``, integer flight index); all rates are per flight and all
  standard deviations of random walks are per square root of a flight.
- The config is a frozen dataclass validated in ``__post_init__``: a bad value raises
  ``ValueError``, never an ``assert``. It round-trips through JSON (``to_json``/``from_json``).
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field
from typing import Any, Literal, get_args

import numpy as np

from .hypotheses import RateHypothesis
from .laws import LAWS, DegradationLaw, ExponentialLaw, law_for

__all__ = ["RATE_BASES", "RATE_WEIGHTINGS", "PrognoserConfig", "RateBasis", "RateWeighting"]

RateBasis = Literal["constant", "affine", "quadratic", "exponential"]
#: how a bank of rate hypotheses is weighed (``PrognoserConfig.rate_weighting``)
RateWeighting = Literal["predictive", "evidence"]
RATE_WEIGHTINGS: tuple[str, ...] = get_args(RateWeighting)

#: number of RLS parameters of each growth-rate basis (:data:`.laws.LAWS`): ``dh/dk = theta .
#: phi(h)``, or for ``"exponential"`` theta = (a, r) of the log-level line ``ln(h + c) = a + r k``
RATE_BASES: dict[str, int] = {name: law.n_params for name, law in LAWS.items()}

_CONFIG_VERSION = 1


@dataclass(frozen=True)
class PrognoserConfig:
    """Hyper-parameters of :class:`~server.phm.prognosis.ParticleFilterPrognoser`.

    Attributes
    ----------
    n_particles:
        Number of particles N [-]. Default 200 (paper, section 5.1).
    process_noise_std:
        Standard deviation of the severity random walk added at each flight [1/sqrt(flight)];
        explicit and strictly positive (a zero process noise collapses the particle cloud).
        Default 0.01, the trained chain's: it lets the cloud follow a fault that grows faster
        or slower than the design prior (docs/TUNING.md, Prognosis). On smooth synthetic
        series the filter's tests and benchmark keep 0.004 (:data:`.generic.GENERIC_CONFIG`).
    prediction_noise_std:
        Standard deviation of the severity random walk of the long-term prediction
        [1/sqrt(flight)], or None for ``process_noise_std``. The filter's process noise lets
        the cloud follow the measurements; the prediction's is the fault's own
        flight-to-flight randomness, which training can learn from the design runs
        (``TrainingConfig.prediction_noise``). Left out of the config document when None, so
        documents and filter states made before it read back unchanged.
    rate_basis:
        Growth-rate model ``dh/dk = theta . phi(h)`` [1/flight], one class of :mod:`.laws` each
        (:attr:`law`): ``"constant"`` phi = [1] (linear wear, Archard at constant load),
        ``"affine"`` phi = [1, h] (linear + exponential growth), ``"quadratic"`` phi =
        [1, h, h^2] (accelerating); these are tuned by RLS on the increments of the filtered
        severity. ``"exponential"``: dh/dk = r (h + c) with the shape ``growth_offset`` c fixed,
        tuned by RLS on the severity *level*, ln(h + c) = a + r k (see :mod:`.degradation`).
    growth_offset:
        Shape c of the ``"exponential"`` law [-] (severity at which growth would stop, negated):
        large c is near-linear wear, small c near-pure exponential growth; c < -1 is growth
        that slows down towards -c > 1 (r < 0; a worn drive that hands its load to its
        partner). Unused by the others.
    initial_rate_std:
        Prior standard deviation of r [1/flight] for the ``"exponential"`` law; ``None`` ->
        35 % of the first-trial r (the spread of fault-to-failure spans between patterns).
    initial_theta:
        First-trial RLS parameters, one per basis term; ``None`` -> a constant rate of
        ``initial_rate`` per flight and zeros for the other terms (``"exponential"``: a = 0,
        re-set at the first measurement, and r giving ``initial_rate`` at h = 0.5).
    initial_rate:
        First-trial growth rate [1/flight] used when ``initial_theta`` is None
        (1/250: the middle of the 150-400 flight fault-to-failure span of the campaigns).
    rls_forgetting:
        RLS forgetting factor lambda in (0, 1] [-]; memory about 1/(1 - lambda) flights.
    rls_initial_cov:
        Diagonal of the initial RLS covariance matrix P0 [-] (large -> trust data quickly).
    rls_max_trace:
        Upper bound of trace(P) [-]; guards against covariance wind-up when the regressor is not
        exciting (forgetting with a constant regressor makes P grow without bound).
    min_rate:
        Floor of the growth rate [1/flight] (progressive faults never heal); keeps every
        prediction finite up to ``max_horizon_flights``.
    resample_threshold:
        Systematic resampling happens when ESS < resample_threshold * N [-]. Default 0.5.
    initial_severity_max:
        Prior before any measurement: severity uniform on [0, initial_severity_max] [-]. The first
        measurement re-initialises the cloud around the inverted measurement.
    max_horizon_flights:
        Long-term prediction stops here [flight]; particles that have not failed by then are
        reported as "beyond horizon" (RUL = inf).
    prediction_steps:
        Target number of Euler steps of one long-term prediction [-]; the step (an integer number
        of flights, >= 1) is chosen from the expected time to failure, and doubles every
        ``prediction_steps`` steps so that the cost stays bounded.
    monotone_rate:
        If True, the per-particle parameter draws of the long-term prediction keep the
        severity-dependent terms >= 0 (theta_j >= 0 for j >= 1): the growth rate does not fall as
        severity grows (Arrhenius insulation damage, grease aging, Archard wear at a steady
        load). Without it, draws with a negative slope stall below the threshold and put mass
        "beyond the horizon"; training turns it off only for a mode whose design runs slow
        down (winglet rod-end wear: the partner drive takes the load).
    param_uncertainty_scale:
        Multiplier of the RLS parameter covariance used to draw one parameter vector per particle
        in the long-term prediction [-]; 0 disables parameter uncertainty.
    quantile_levels:
        RUL quantile levels reported [-], each in (0, 1).
    pof_horizons_flights:
        Horizons [flight] for the probability of failure within k flights.
    histogram_bins:
        Number of bins of the RUL histogram [-].
    rate_bounds:
        Plausible range ``(low, high)`` of the growth rate at mid-life, ``g(0.5; theta)``
        [1/flight], or None. Where the law is used (propagation, and every particle's parameter
        sample of the prediction) it is scaled into this range; the RLS estimate itself is left
        free. Early in a life the increments of the filtered severity are mostly noise and can
        drive the tuned law to an implausibly slow or fast rate (training sets the range from
        the slowest and fastest design runs, widened by ``TrainingConfig.slow_rate_margin``
        and ``fast_rate_margin``).
    rate_prior_tail:
        Prior probability that the fault's rate lies off the design's range [-], in [0, 1);
        ``"exponential"`` law only. 0: the rate prior is the normal N(r0, sd^2) of
        ``initial_theta`` and ``initial_rate_std``. Above 0 it is a mixture: that normal with
        weight 1 - tail, and the same normal scaled by each of
        ``CONSTANTS.rate_tail_factors`` (3 times slower to 6.75 times faster) sharing the
        tail. Each component is tuned by its own RLS and weighted by how well it predicted the
        measurements (:mod:`.mixture`): a fault far faster or slower than any in design pulls
        the rate within a few flights instead of fighting a light-tailed prior. Left out of
        the config document when 0, so documents and states made before it read back
        unchanged.
    rate_hypotheses:
        The bank of rate hypotheses (:mod:`.hypotheses`), ``"exponential"`` law only: one
        rate prior per band of fault-to-failure spans, each with its prior weight, each tuned
        by its own RLS and weighed as ``rate_weighting`` says (:mod:`.mixture`); the RUL
        distribution names the leading one. Empty: ``rate_prior_tail`` decides. Left out of
        the config document when empty.
    rate_weighting:
        How the bank's hypotheses are weighed (:mod:`.mixture`): ``"predictive"``, each by
        its own RLS's predictive likelihood of every new measurement, forgotten at the RLS's
        rate; ``"evidence"``, each by its band's prior kept whole against the measurements'
        discounted information (the Bayesian evidence of the band). Left out of the config
        document at ``"predictive"``.
    guard_horizon:
        Flights ahead of the online guard's feature forecasts (:mod:`.guard`); 0: no guard.
    guard_gain:
        Step of the guard's widening per scored forecast [log(1 + RUL)] (conformal PID's
        learning rate). Default 0.1.
    guard_miss_rate:
        Share of forecasts the guard expects to miss (its forecast interval is the central
        1 - this) [-]. Default 0.1.

    The three fields above are left out of the config document at their defaults, so documents
    and states made before them read back unchanged.
    """

    n_particles: int = 200
    process_noise_std: float = 0.01
    rate_basis: RateBasis = "affine"
    growth_offset: float = 0.5
    initial_rate_std: float | None = None
    initial_theta: tuple[float, ...] | None = None
    initial_rate: float = 1.0 / 250.0
    rls_forgetting: float = 0.97
    rls_initial_cov: float = 1.0
    rls_max_trace: float = 10.0
    min_rate: float = 1e-5
    resample_threshold: float = 0.5
    initial_severity_max: float = 0.5
    max_horizon_flights: int = 2000
    prediction_steps: int = 50
    param_uncertainty_scale: float = 1.0
    monotone_rate: bool = True
    quantile_levels: tuple[float, ...] = (0.05, 0.25, 0.5, 0.75, 0.95)
    pof_horizons_flights: tuple[int, ...] = (10, 25, 50)
    histogram_bins: int = 30
    rate_bounds: tuple[float, float] | None = None
    prediction_noise_std: float | None = None
    rate_prior_tail: float = 0.0
    rate_hypotheses: tuple[RateHypothesis, ...] = ()
    rate_weighting: RateWeighting = "predictive"
    guard_horizon: int = 0
    guard_gain: float = 0.1
    guard_miss_rate: float = 0.1
    _version: int = field(default=_CONFIG_VERSION, repr=False, compare=False)

    def __post_init__(self) -> None:
        for name in ("n_particles", "max_horizon_flights", "prediction_steps", "histogram_bins"):
            object.__setattr__(self, name, _whole(name, getattr(self, name)))
        object.__setattr__(self, "pof_horizons_flights", tuple(
            _whole("pof_horizons_flights", h) for h in self.pof_horizons_flights))
        if self.n_particles < 2:
            raise ValueError(f"n_particles must be >= 2, got {self.n_particles}")
        _positive("process_noise_std", self.process_noise_std)
        if self.prediction_noise_std is not None:
            _positive("prediction_noise_std", self.prediction_noise_std)
        n_params = law_for(self.rate_basis).n_params
        if self.initial_theta is not None:
            theta = tuple(float(v) for v in self.initial_theta)
            if len(theta) != n_params:
                raise ValueError(
                    f"initial_theta needs {n_params} values for basis "
                    f"{self.rate_basis!r}, got {len(theta)}"
                )
            if not all(math.isfinite(v) for v in theta):
                raise ValueError("initial_theta must be finite")
            object.__setattr__(self, "initial_theta", theta)
        _positive("initial_rate", self.initial_rate)
        c = float(self.growth_offset)
        if not (math.isfinite(c) and (c > 0.0 or c < -1.0)):
            raise ValueError("growth_offset must be > 0 (growth) or < -1 (saturating growth that "
                             f"still reaches the threshold 1), got {self.growth_offset}")
        if self.initial_rate_std is not None:
            _positive("initial_rate_std", self.initial_rate_std)
        if not (0.0 < self.rls_forgetting <= 1.0):
            raise ValueError(f"rls_forgetting must be in (0, 1], got {self.rls_forgetting}")
        _positive("rls_initial_cov", self.rls_initial_cov)
        _positive("rls_max_trace", self.rls_max_trace)
        _positive("min_rate", self.min_rate)
        if not (0.0 < self.resample_threshold <= 1.0):
            raise ValueError(f"resample_threshold must be in (0, 1], got {self.resample_threshold}")
        if not (0.0 <= self.initial_severity_max < 1.0):
            raise ValueError("initial_severity_max must be in [0, 1)")
        for name in ("max_horizon_flights", "prediction_steps", "histogram_bins"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be a positive int, got {getattr(self, name)!r}")
        if not isinstance(self.monotone_rate, bool):
            raise ValueError("monotone_rate must be a bool")
        if not (math.isfinite(self.param_uncertainty_scale) and self.param_uncertainty_scale >= 0):
            raise ValueError("param_uncertainty_scale must be finite and >= 0")
        levels = tuple(float(q) for q in self.quantile_levels)
        if not levels or any(not (0.0 < q < 1.0) for q in levels) or list(levels) != sorted(levels):
            raise ValueError("quantile_levels must be increasing values in (0, 1)")
        object.__setattr__(self, "quantile_levels", levels)
        if any(h < 1 for h in self.pof_horizons_flights):
            raise ValueError("pof_horizons_flights must be positive ints")
        if self.rate_bounds is not None:
            lo, hi = (float(v) for v in self.rate_bounds)
            if not (math.isfinite(lo) and math.isfinite(hi) and 0.0 < lo < hi):
                raise ValueError("rate_bounds must be finite with 0 < low < high")
            object.__setattr__(self, "rate_bounds", (lo, hi))
        tail = self.rate_prior_tail
        if isinstance(tail, bool) or not (isinstance(tail, int | float) and 0.0 <= tail < 1.0):
            raise ValueError(f"rate_prior_tail must be in [0, 1), got {tail!r}")
        if tail > 0.0 and self.rate_basis != "exponential":
            raise ValueError("rate_prior_tail needs rate_basis 'exponential', got "
                             f"{self.rate_basis!r}")
        object.__setattr__(self, "rate_prior_tail", float(tail))
        self._check_hypotheses()
        self._check_guard()
        if self._version != _CONFIG_VERSION:
            raise ValueError(f"unsupported config version {self._version}")

    def _check_hypotheses(self) -> None:
        # a document's entries arrive as dicts (from_dict): read here, in one place
        bank = tuple(RateHypothesis.from_dict(h) if isinstance(h, dict) else h
                     for h in self.rate_hypotheses)
        if not all(isinstance(h, RateHypothesis) for h in bank):
            raise ValueError("rate_hypotheses must be RateHypothesis entries")
        if bank and self.rate_basis != "exponential":
            raise ValueError("rate_hypotheses need rate_basis 'exponential', got "
                             f"{self.rate_basis!r}")
        if bank and self.rate_prior_tail > 0.0:
            raise ValueError("rate_hypotheses replace rate_prior_tail: set one of them")
        if len({h.name for h in bank}) != len(bank):
            raise ValueError("rate_hypotheses need distinct names")
        if self.rate_weighting not in RATE_WEIGHTINGS:
            raise ValueError(f"rate_weighting must be one of {list(RATE_WEIGHTINGS)}, got "
                             f"{self.rate_weighting!r}")
        if self.rate_weighting == "evidence" and not bank:
            raise ValueError("rate_weighting 'evidence' weighs a bank: it needs rate_hypotheses")
        if any(math.copysign(1.0, h.rate) != math.copysign(1.0, self.growth_offset)
               for h in bank):
            raise ValueError("every rate hypothesis's rate has the sign of growth_offset "
                             "(dh/dk = r (h + c) > 0)")
        object.__setattr__(self, "rate_hypotheses", bank)

    @property
    def rate_mixture(self) -> bool:
        """Whether the rate prior is a mixture (a bank of hypotheses, or the tail's scaled
        copies) tuned one RLS per component."""
        return bool(self.rate_hypotheses) or self.rate_prior_tail > 0

    def _check_guard(self) -> None:
        object.__setattr__(self, "guard_horizon", _whole("guard_horizon", self.guard_horizon))
        if not 0 <= self.guard_horizon <= 100:
            raise ValueError(f"guard_horizon must be in 0..100 flights, got {self.guard_horizon}")
        _positive("guard_gain", self.guard_gain)
        if not (isinstance(self.guard_miss_rate, int | float)
                and 0.0 < self.guard_miss_rate < 0.5):
            raise ValueError(f"guard_miss_rate must be in (0, 0.5), got {self.guard_miss_rate!r}")

    @property
    def law(self) -> DegradationLaw:
        """The degradation law of ``rate_basis``, with this config's shape (:mod:`.laws`)."""
        return law_for(self.rate_basis).from_config(self)

    @property
    def n_params(self) -> int:
        """Number of RLS parameters of the growth-rate basis."""
        return law_for(self.rate_basis).n_params

    @property
    def prediction_noise(self) -> float:
        """The long-term prediction's severity random walk [1/sqrt(flight)]."""
        return self.process_noise_std if self.prediction_noise_std is None \
            else self.prediction_noise_std

    @property
    def theta0(self) -> tuple[float, ...]:
        """First-trial RLS parameter vector."""
        if self.initial_theta is not None:
            return self.initial_theta
        return self.law.first_trial(self.initial_rate)

    @property
    def rate_prior_std(self) -> float:
        """Prior standard deviation of r of the ``"exponential"`` law [1/flight]."""
        return ExponentialLaw.rate_prior_std(self)

    def to_dict(self) -> dict[str, Any]:
        data = asdict(self)
        data.pop("_version")
        data["initial_theta"] = None if self.initial_theta is None else list(self.initial_theta)
        data["quantile_levels"] = list(self.quantile_levels)
        data["pof_horizons_flights"] = list(self.pof_horizons_flights)
        data["rate_bounds"] = None if self.rate_bounds is None else list(self.rate_bounds)
        if self.prediction_noise_std is None:
            del data["prediction_noise_std"]
        if self.rate_prior_tail == 0.0:
            del data["rate_prior_tail"]
        if self.rate_hypotheses:
            data["rate_hypotheses"] = [h.to_dict() for h in self.rate_hypotheses]
        else:
            del data["rate_hypotheses"]
        for name, default in _LEFT_OUT_AT_DEFAULT.items():
            if data[name] == default:
                del data[name]
        return {"version": _CONFIG_VERSION, "kind": "pf_prognoser_config", **data}

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), sort_keys=True)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> PrognoserConfig:
        data = dict(data)
        version = data.pop("version", None)
        if version != _CONFIG_VERSION:
            raise ValueError(f"unsupported config version {version!r}")
        data.pop("kind", None)
        known = {f for f in cls.__dataclass_fields__ if not f.startswith("_")}
        unknown = set(data) - known
        if unknown & _RETIRED:
            raise ValueError(f"config fields {sorted(unknown & _RETIRED)} belong to the joint "
                             "state-parameter filter, retired (docs/PROGNOSIS.md): train the "
                             "model again")
        if unknown:
            raise ValueError(f"unknown config fields {sorted(unknown)}")
        for key in ("initial_theta", "quantile_levels", "pof_horizons_flights", "rate_bounds"):
            if data.get(key) is not None:
                data[key] = tuple(data[key])
        data["rate_hypotheses"] = tuple(data.get("rate_hypotheses") or ())  # dicts: read below
        return cls(**data)

    @classmethod
    def from_json(cls, text: str) -> PrognoserConfig:
        return cls.from_dict(json.loads(text))


#: fields written to the config document only when they differ from these defaults
_LEFT_OUT_AT_DEFAULT: dict[str, Any] = {
    "guard_horizon": 0, "guard_gain": 0.1, "guard_miss_rate": 0.1,
    "rate_weighting": "predictive"}

#: fields of the retired joint state-parameter filter; a document that sets any is refused
_RETIRED = frozenset({"joint_rate", "rate_prior_log_std", "rate_kernel_shrinkage"})


def _positive(name: str, value: float) -> None:
    if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
        raise ValueError(f"{name} must be finite and > 0, got {value!r}")


def _whole(name: str, value: object) -> int:
    """A count given as an int or as a whole float (5000.0 is 5000); anything else refused."""
    if isinstance(value, bool):
        raise ValueError(f"{name} must be a whole number, got {value!r}")
    if isinstance(value, int | np.integer):
        return int(value)
    if isinstance(value, float | np.floating) and math.isfinite(value) \
            and float(value).is_integer():
        return int(value)
    raise ValueError(f"{name} must be a whole number, got {value!r}")
