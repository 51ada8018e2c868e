"""Evaluation of the PHM chain on simulated campaigns (paper sections 4.3 and 5): detection,
classification, prognosis metrics and timings, as the service runs the chain.

Entry points: :func:`evaluate_campaign` (library), ``hmsm evaluate`` (see
:mod:`server.evaluation.cli`), ``python -m server.evaluation.rul_plot`` (one mode's RUL plot).
"""

from .core import (
    ALPHA,
    N_PREDICTIONS,
    PAPER_TABLE2,
    evaluate_campaign,
    evaluate_patterns,
    pattern_prognosis,
    prediction_instants,
    run_pattern,
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
