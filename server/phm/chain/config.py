"""Tuned constants of the chain's run-time glue (between detection, classifier and filter).
The reasons and the alternatives scored are in ``docs/TUNING.md``."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["ChainConfig", "CHAIN"]


@dataclass(frozen=True)
class ChainConfig:
    #: [1/flight] weight kept by older flights' class evidence per flight: recent flights, at
    #: a larger severity, tell more; 0.8 keeps about five flights of memory
    class_evidence_decay: float = 0.8
    #: [flights] valid flights averaged into the classifier's input: bridges flights on which
    #: an intermittent signature (backlash on load reversals) does not show
    classifier_flights: int = 3
    #: [flights] residual history kept per actuator for a filter replay (longer than any
    #: fault-to-failure span the design campaigns simulate)
    history_flights: int = 600


#: the configuration the service runs
CHAIN = ChainConfig()
