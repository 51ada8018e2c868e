"""The PHM chain of one actuator, flight by flight, as the service runs it (paper Figure 15).

features (whole aircraft) -> standardised residuals z -> detection per actuator, against the
actuator's own reference (self-referenced residuals, :mod:`server.phm.detection`) -> after an
alarm: classification of the self-referenced residuals of the last three flights (class
log-probabilities accumulated since the alarm) -> for a progressive mode: particle-filter
prognosis on the mode's measurement feature, a physical-unit residual with the actuator's own
offset removed.

Units and time base: one step per flight; ``flight_index`` counts the flights an actuator has
seen since installation. Severity is normalised (failure threshold 1.0).

Monitored units: each actuator carries its own six features, read on the flights its inverter
switches; a winglet drive also carries its rod-end play ``F_REWEAR``, read on the flights it
stands by (the active-standby tab alternates its active drive by flight). The classifier sees
the seven generic features of the alarmed actuator (``F_REWEAR`` = 0 for the wingtip).

Modules: :mod:`.model` (the trained model document and its reader), :mod:`.state` (an
actuator's state between flights), :mod:`.inputs` (what each stage is fed), :mod:`.run` (one
flight), :mod:`.prognose` (the filter step), :mod:`.config` (tuned constants). Everything
persists as JSON; never pickle.
"""

from server.vocabulary import GENERIC_FEATURES, OWN_FEATURE, PROGRESSIVE

from .config import CHAIN, ChainConfig
from .inputs import (
    actuator_feature_names,
    classifier_vector,
    measurement_values,
    self_residuals,
    surface_of,
)
from .model import MODEL_FORMAT, MeasurementSpec, PhmModel, is_model_document, read_model_document
from .run import ActuatorOutcome, MeasurementHook, analyze_flight
from .state import HEALTH_FORMAT, ActuatorHealth

__all__ = [
    "MODEL_FORMAT",
    "HEALTH_FORMAT",
    "MeasurementHook",
    "PROGRESSIVE",
    "GENERIC_FEATURES",
    "OWN_FEATURE",
    "CHAIN",
    "ChainConfig",
    "actuator_feature_names",
    "classifier_vector",
    "measurement_values",
    "self_residuals",
    "MeasurementSpec",
    "surface_of",
    "PhmModel",
    "is_model_document",
    "read_model_document",
    "ActuatorHealth",
    "ActuatorOutcome",
    "analyze_flight",
]
