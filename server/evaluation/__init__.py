"""Evaluation of the PHM chain on simulated campaigns (paper sections 4.3 and 5): detection,
classification, prognosis metrics and timings, as the service runs the chain.

Entry points: :func:`evaluate_campaign` (library), ``hmsm evaluate`` (see
:mod:`server.evaluation.cli`), ``python -m server.evaluation.rul_plot`` (one mode's RUL plot).

Modules: :mod:`.runner` runs the chain over the patterns, :mod:`.scoring` scores the traces
(intervals from :mod:`.bootstrap`), :mod:`.summary` is the figures' document (``summary.json``).
"""

from server.vocabulary import PAPER_TABLE2

from .runner import evaluate_campaign, evaluate_patterns, run_pattern
from .scoring import (
    ALPHA,
    N_PREDICTIONS,
    pattern_prognosis,
    prediction_instants,
    select_prediction_flights,
    summarise_detection,
    summarise_prognosis,
)

__all__ = [
    "ALPHA",
    "N_PREDICTIONS",
    "PAPER_TABLE2",
    "evaluate_campaign",
    "evaluate_patterns",
    "pattern_prognosis",
    "prediction_instants",
    "run_pattern",
    "select_prediction_flights",
    "summarise_detection",
    "summarise_prognosis",
]
