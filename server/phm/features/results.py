"""What the extraction gives: the feature names of an aircraft and the sensors each reads, the
operating-condition names, and the per-flight results (:class:`FeatureTrack` at 80 Hz,
:class:`FeatureSummary` per flight, :class:`FlightFeatures` for the aircraft).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from server.vocabulary import POSITIONS, position_features

__all__ = ["FEATURE_SENSORS", "AIRCRAFT_FEATURES", "CONDITION_NAMES", "FeatureTrack",
           "FeatureSummary", "FlightFeatures"]


#: the sensors each generic feature reads: its own actuator's, both winglet drives' for
#: F_REWEAR. Every feature's validity windows read the motor speed, hence the resolver
FEATURE_SENSORS: dict[str, tuple[str, ...]] = {
    "F_TTS": ("current", "voltage", "resolver"), "F_DMD": ("current", "voltage", "resolver"),
    "F_SE": ("current", "voltage", "resolver"), "F_BDO": ("current", "voltage", "resolver"),
    "F_MTEL": ("current", "resolver", "lvdt"), "F_MTWEAR": ("current", "resolver", "lvdt"),
    "F_REWEAR": ("resolver", "lvdt"),
}


#: the 20 feature names of one aircraft, ``"<position>.<feature>"``: six per drive, and the
#: rod-end play of each winglet drive
AIRCRAFT_FEATURES: tuple[str, ...] = tuple(
    f"{p}.{f}" for p in POSITIONS for f in position_features(p))


#: per-actuator operating conditions used by the baselines
CONDITION_NAMES: tuple[str, ...] = (
    "temp_ground_c", "temp_mean_c", "load_rms_n", "speed_rms_rad_s", "temp_winding_est_c",
    "mtel_drag_weight_per_nm")


@dataclass
class FeatureTrack:
    """One feature over one flight at 80 Hz.

    ``series[k]`` is the filtered feature at step k (NaN before the first valid step, held
    between valid steps); ``valid[k]`` says whether step k contributed.
    """

    series: np.ndarray  # (n_steps,)
    valid: np.ndarray  # (n_steps,) bool
    value: float  # flight value (NaN if no valid step)
    dispersion: float  # std of the filtered series over valid steps
    n_valid: int

    def summary(self) -> FeatureSummary:
        return FeatureSummary(self.value, self.dispersion, self.n_valid)


@dataclass(frozen=True)
class FeatureSummary:
    """Per-flight summary of one feature."""

    value: float
    dispersion: float
    n_valid: int

    def to_dict(self) -> dict[str, float | int]:
        return {"value": self.value, "dispersion": self.dispersion, "n_valid": self.n_valid}


@dataclass
class FlightFeatures:
    """All 20 features of one flight plus the operating conditions of each actuator."""

    summaries: dict[str, FeatureSummary]  # AIRCRAFT_FEATURES -> summary
    conditions: dict[str, dict[str, float]]  # position -> CONDITION_NAMES -> value
    tracks: dict[str, FeatureTrack] | None = None  # only when asked for
    #: channel -> signal-quality figures (:mod:`server.phm.signal_quality`); empty when the
    #: features were stored without them
    quality: dict[str, dict[str, float]] = field(default_factory=dict)

    def values(self) -> dict[str, float]:
        return {k: s.value for k, s in self.summaries.items()}

    def to_dict(self) -> dict[str, object]:
        return {"summaries": {k: s.to_dict() for k, s in self.summaries.items()},
                "conditions": self.conditions, "quality": self.quality}
