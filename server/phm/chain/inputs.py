"""What the chain feeds its stages for one actuator: the monitored feature names, the
classifier's input vector, the physical residuals the particle filter measures."""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from server.vocabulary import GENERIC_FEATURES, WINGLET_PAIR, position_features

from ..baselines import FleetBaseline
from ..detection import DetectionResult, DetectionState
from .config import CHAIN

__all__ = ["actuator_feature_names", "classifier_vector", "measurement_values",
           "self_residuals", "surface_of"]


def actuator_feature_names(position: str) -> list[str]:
    """Aircraft feature names monitored for one actuator position: its own six, plus its
    rod-end play for a winglet drive."""
    return [f"{position}.{g}" for g in position_features(position)]


def surface_of(position: str) -> str:
    """``WL`` for the winglet drives, the position itself (``WT``) for the wingtip drive."""
    return "WL" if position in WINGLET_PAIR else "WT"


def _generic(name: str) -> str:
    return name.split(".", 1)[1]


def classifier_vector(detection: DetectionState, position: str) -> np.ndarray:
    """The classifier's input for an actuator: per generic feature, the mean self-referenced
    residual of its last ``CHAIN.classifier_flights`` valid flights (the detection history),
    compressed as ``sign(x) log(1 + |x|)``; missing features count as 0.

    The short mean bridges flights on which an intermittent signature does not show (backlash
    only shows on flights whose load changes sign); the compression lets the linear SVM weigh
    *which* features left their band rather than by how much (residuals span 0 to 100+).
    """
    out = np.zeros(len(GENERIC_FEATURES))
    for name in actuator_feature_names(position):
        hist = detection.history.get(name) or []
        if hist:
            v = float(np.mean(hist[-CHAIN.classifier_flights:]))
            out[GENERIC_FEATURES.index(_generic(name))] = math.copysign(math.log1p(abs(v)), v)
    return out


def measurement_values(residuals: Mapping[str, float], position: str) -> dict[str, float]:
    """Physical-unit residuals of an actuator's features by generic name (finite ones only)."""
    out = {}
    for name in actuator_feature_names(position):
        v = residuals.get(name, math.nan)
        if v is not None and math.isfinite(v):
            out[_generic(name)] = float(v)
    return out


def self_residuals(baseline: FleetBaseline, z: Mapping[str, float],
                   det: DetectionResult) -> dict[str, float]:
    """Physical-unit residuals with the actuator's own offset (learned by detection from its
    reference flights) removed: what the particle filter measures."""
    return baseline.to_physical({n: v - det.offset[n] for n, v in z.items()
                                 if n in det.offset})
