"""Fault detection: running feature distributions against their healthy baselines.

Time base: one judgement per flight and monitored unit (an actuator ``WL1``/``WL2``/``WT``
with its six features, and a winglet drive's rod-end play ``F_REWEAR``). Inputs are the
standardised residuals ``z`` of :class:`server.phm.baselines.FleetBaseline`. One module per
job:

* :mod:`.config`: the hyper-parameters (:class:`DetectionConfig`, tuned defaults) and the
  names of units and features;
* :mod:`.statistics`: each actuator against its own first flights, running window statistics;
* :mod:`.evidence`: a flight's scatter follows its recording's length;
* :mod:`.detector`: the fitted model (:class:`FaultDetector`): offsets, evidence shares and
  bands for a stated false-alarm rate, learned on healthy design flights, and its document;
* :mod:`.state`: what the judge carries between flights and what it says about one;
* :mod:`.pair`: the winglet pair's rule, a coupled feature's evidence to the drive that moved
  further;
* :mod:`.judge`: the online judge (:func:`update_units`), one flight of an aircraft's units,
  the one entry point of the chain, training and the evaluation;
* :mod:`.sequences`: the same judge vectorised over flight sequences, for fitting the bands
  and the healthy alarm rate.

The tuned values and how they were chosen: docs/TUNING.md, Detection.
"""

from .config import (
    DEFAULT_DIRECTIONS,
    DEFAULT_FLEET_REFERENCED,
    DEFAULT_MIN_WINDOWS,
    DETECTION_DEFAULTS,
    UNITS,
    DetectionConfig,
    generic_feature,
    unit_features,
    unit_of,
)
from .detector import DETECTOR_FORMAT, FaultDetector
from .evidence import MAX_EVIDENCE_SHARE, MIN_EVIDENCE_SPREAD, evidence_shares
from .judge import decide, new_state, new_states, observe, update_units
from .pair import PAIR_COUPLED_FEATURES, held_sequence, partner_held
from .sequences import (
    SequenceJudgement,
    confidence_sequence,
    first_alarms,
    healthy_statistics,
    judge_sequence,
)
from .state import STATE_FORMAT, DetectionResult, DetectionState, Observation
from .statistics import offset_components, running_statistics, self_referenced_sequence

__all__ = [
    "DEFAULT_DIRECTIONS",
    "DEFAULT_FLEET_REFERENCED",
    "DEFAULT_MIN_WINDOWS",
    "DETECTION_DEFAULTS",
    "DETECTOR_FORMAT",
    "MAX_EVIDENCE_SHARE",
    "MIN_EVIDENCE_SPREAD",
    "PAIR_COUPLED_FEATURES",
    "STATE_FORMAT",
    "UNITS",
    "DetectionConfig",
    "DetectionResult",
    "DetectionState",
    "FaultDetector",
    "Observation",
    "SequenceJudgement",
    "confidence_sequence",
    "decide",
    "evidence_shares",
    "first_alarms",
    "generic_feature",
    "healthy_statistics",
    "judge_sequence",
    "held_sequence",
    "new_state",
    "new_states",
    "observe",
    "offset_components",
    "partner_held",
    "running_statistics",
    "self_referenced_sequence",
    "unit_features",
    "unit_of",
    "update_units",
]
