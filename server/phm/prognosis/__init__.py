"""Failure prognosis: particle filter on fault severity, RLS-tuned degradation, RUL prediction.

Conventions: severity normalised so that the failure threshold is 1.0; time in flights (flight
hours kept alongside when given); every random draw from a generator whose state lives in the
filter state; everything persists as versioned JSON (npz optional), never pickle.
See docs/PROGNOSIS.md for the model choices and sources.
"""

from .config import RATE_BASES, PrognoserConfig, RateBasis
from .constants import CONSTANTS, PrognosisConstants
from .degradation import growth_rate, regressor, rls_update
from .filter import (
    ParticleFilterPrognoser,
    PrognoserState,
    StaleStateError,
    effective_sample_size,
    systematic_resample,
)
from .forecast import RulForecast, backtest_forecasts, forecast_rul
from .generic import GENERIC_CONFIG, PriorDominatedWarning, estimate_noise_std
from .law_average import LawAverageConfig
from .laws import (
    LAWS,
    AffineLaw,
    ConstantLaw,
    DegradationLaw,
    ExponentialLaw,
    PolynomialLaw,
    QuadraticLaw,
    RlsMeasurement,
    law_for,
)
from .measurement import MeasurementModel
from .onset import growth_onset
from .predictor import RulDistribution, propagate_to_threshold, summarise_rul, weighted_quantiles

__all__ = [
    "CONSTANTS",
    "GENERIC_CONFIG",
    "LawAverageConfig",
    "LAWS",
    "RATE_BASES",
    "AffineLaw",
    "ConstantLaw",
    "DegradationLaw",
    "ExponentialLaw",
    "MeasurementModel",
    "ParticleFilterPrognoser",
    "PolynomialLaw",
    "PrognosisConstants",
    "PriorDominatedWarning",
    "PrognoserConfig",
    "PrognoserState",
    "QuadraticLaw",
    "RateBasis",
    "RlsMeasurement",
    "RulDistribution",
    "RulForecast",
    "StaleStateError",
    "backtest_forecasts",
    "effective_sample_size",
    "estimate_noise_std",
    "forecast_rul",
    "growth_onset",
    "growth_rate",
    "law_for",
    "propagate_to_threshold",
    "regressor",
    "rls_update",
    "summarise_rul",
    "systematic_resample",
    "weighted_quantiles",
]
