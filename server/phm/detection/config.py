"""Detection's hyper-parameters (:class:`DetectionConfig`, whose defaults are the tuned values)
and the names of what it monitors: the units and their features."""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

from server.vocabulary import GENERIC_FEATURES, OWN_FEATURE, POSITIONS, PROGRESSIVE, REWEAR_FEATURE

__all__ = [
    "DEFAULT_DIRECTIONS",
    "DEFAULT_FLEET_REFERENCED",
    "DEFAULT_MIN_WINDOWS",
    "DETECTION_DEFAULTS",
    "DetectionConfig",
    "UNITS",
    "generic_feature",
    "unit_features",
    "unit_of",
]

#: monitored units and the prefix of their feature names: the actuators
UNITS: tuple[str, ...] = POSITIONS


@dataclass(frozen=True)
class DetectionConfig:
    """Hyper-parameters of :class:`~server.phm.detection.FaultDetector`; the defaults are the
    tuned values (how they were chosen: docs/TUNING.md, Detection). A fitted detector stores
    its values in its document.

    Attributes
    ----------
    windows:
        Running-window lengths [flight]: 1 reacts within one flight to step faults (SE, BDO);
        3 and 8 accumulate the evidence of slow drifts.
    alarm_confidence:
        Confidence at which a unit alarms [-]: the paper's 0.98, ``|S_w| >= b_w + 2.05``.
    band_floor:
        Smallest band ``b_w`` [standard error]: a feature with few healthy flights still gets
        at least this band.
    false_alarm_rate:
        False alarms per monitored unit and healthy flight the bands are set for [1/flight],
        shared out among the unit's (feature, window) tests (:mod:`.detector`).
    scale_quantile:
        Upper quantile of the healthy judged ``S_w`` at which its normal scale ``s_w`` is
        matched, ``s_w = Q_p / z_p`` [-]: far enough out to see heavier-than-normal tails,
        near enough to be estimated from a few hundred healthy flights.
    directions:
        Generic feature -> +1 (the fault makes it grow), -1 (fall), 0 (either) [-]: every
        feature grows with its fault, so the test is one-sided.
    pool_positions:
        One band per generic feature (per surface where they differ, below), its scale
        measured on those positions' healthy flights together: more healthy flights behind
        each band, the same physics on each drive.
    surface_split_ratio:
        With ``pool_positions``, a generic feature is fitted per surface (the two winglet
        drives together, the wingtip alone) when one surface's within-unit scatter on the
        healthy design flights exceeds the other's by more than this factor [-]; otherwise
        every position together (on the shipped design: ``F_MTWEAR`` alone, docs/TUNING.md).
        ``inf``: always pooled.
    min_windows:
        Generic feature -> shortest window allowed to raise an alarm [flight]: 3 for the five
        progressive faults' features (they build up over hundreds of flights, while single
        healthy flights stray far); absent (F_SE, F_BDO, step faults): 1. F_MTWEAR has a
        value only on flights that pressed both screw flanks, so its 3 flights are the last 3
        such flights.
    reference_flights:
        Valid flights of each actuator that form its own reference [flight]
        (:mod:`.statistics`); 0 is the pure fleet test.
    window_clip:
        Residuals are clipped to +-``window_clip`` in windows longer than one flight
        [flight-scatter sd]: one odd flight moves ``S_3`` by at most ``window_clip / sqrt(3)``;
        ``inf`` off.
    median_from:
        Windows of at least this many flights use the running median [flight]: a minority of
        odd flights does not move the statistic; 0 never.
    fleet_referenced:
        Generic features tested against the fleet, not the actuator's own first flights [-]:
        ``F_REWEAR``, which a worn rod end moves far beyond any actuator offset, so a median of
        its first flights would absorb an early wear rather than reference a drive.
    """

    windows: tuple[int, ...] = (1, 3, 8)
    alarm_confidence: float = 0.98
    band_floor: float = 3.0
    false_alarm_rate: float = 3e-5
    scale_quantile: float = 0.99
    directions: Mapping[str, int] = field(
        default_factory=lambda: MappingProxyType(dict.fromkeys(GENERIC_FEATURES, 1)))
    pool_positions: bool = True
    surface_split_ratio: float = 1.5
    min_windows: Mapping[str, int] = field(
        default_factory=lambda: MappingProxyType({OWN_FEATURE[m]: 3 for m in PROGRESSIVE}))
    reference_flights: int = 6
    window_clip: float = 6.0
    median_from: int = 8
    fleet_referenced: tuple[str, ...] = (REWEAR_FEATURE,)


#: the tuned detector (``FaultDetector()``)
DETECTION_DEFAULTS = DetectionConfig()
#: physical direction of each generic feature under its fault: +1 grows, -1 falls, 0 either
DEFAULT_DIRECTIONS: dict[str, int] = dict(DETECTION_DEFAULTS.directions)
#: generic features tested against the fleet rather than the actuator's own first flights
DEFAULT_FLEET_REFERENCED: tuple[str, ...] = DETECTION_DEFAULTS.fleet_referenced
#: shortest alarm window per generic feature
DEFAULT_MIN_WINDOWS: dict[str, int] = dict(DETECTION_DEFAULTS.min_windows)


def generic_feature(name: str) -> str:
    """``"WL1.F_TTS"`` -> ``"F_TTS"``."""
    return name.split(".", 1)[-1]


def unit_of(name: str) -> str:
    """``"WL1.F_TTS"`` -> ``"WL1"``."""
    return name.split(".", 1)[0]


def unit_features(unit: str, feature_names: Iterable[str]) -> list[str]:
    """Feature names (``"<unit>.F_*"``) that belong to ``unit``."""
    return [f for f in feature_names if unit_of(f) == unit]
