"""The summary document (``summary.json``, :func:`summary_document`): every figure and interval,
no per-flight trace and no per-pattern prediction list; keys in this order::

    {"format": "ema-evaluation-summary/1", "evaluation_format": "ema-evaluation/1",
     "created_at": str | None,
     "campaign": {"dir", "kind", "seed", "scale", "render_every", "duration_s", "patterns",
                  "flights", "aircraft": [{"tail", "base", "climate"}]},
     "model": {"format", "sha256", "source", "model_id"?, "training_s"?,
               "classifier_accuracy"?},
     "settings": {"alpha", "lambda", "n_predictions", "point_estimate", ...,
                  "bootstrap": {"resamples", "level", "seed", "unit", "interval"}, "jobs"},
     "detection": {
       "false_alarms": {"healthy_patterns", "healthy_patterns_with_alarm", "healthy_flights",
                        "false_alarm_events", "rate_per_flight", "rate_per_flight_ci",
                        "clusters", "pre_onset_alarms_in_fault_patterns"},
       "per_mode": {MODE: {"patterns", "detected", "rate", "rate_ci",
                           "pct_life_mean", "pct_life_mean_ci", "pct_life_max",
                           "flights_after_onset_mean", "flights_after_onset_mean_ci",
                           "flights_after_onset_max", "other_unit_alarms",
                           "missed": [pattern id]}}},
     "classification": {"classes": [str],
       "at_first_alarm" | "at_confirmation" | "at_last_flight": {"rows", "columns",
           "matrix", "accuracy", "accuracy_ci",
           "per_class": {MODE: {"n", "recall", "recall_ci", "precision"}}},
       "confirmation_rule": {"flights", "probability"},
       "flights_to_confirmation": {"confirmed", "unconfirmed", "mean", "p90", "max",
                                   "ended_before_due"}},
     "prognosis": {MODE: {"ph", "ph_ci", "ph_cone", "ph_cone_ci", "ph_from_detection",
                          "ph_from_detection_ci", "ra", "ra_ci" (RA in %), "ra_fraction",
                          "ra_fraction_ci", "ra_median_pattern", "alpha_lambda",
                          "alpha_lambda_ci" (pass rate), "cra", "cra_ci", "convergence",
                          "convergence_ci",
                          "calibration": {"n_predictions", "central_50", "central_50_ci",
                                          "central_90", "central_90_ci",
                                          "width_50_flights", "width_50_flights_ci",
                                          "width_90_flights", "width_90_flights_ci"},
                          "most_probable": {"point_estimate": "mode", "ph", "ph_ci",
                                            "ph_cone", "ph_cone_ci", "ra", "ra_ci"},
                          "n_patterns", "n_with_predictions", "paper": {"ph", "ra"}}},
     "sensors": {"flights", "flights_with_finding", "healthy_cycle_flights",
                 "healthy_cycle_flights_with_finding",
                 "by_channel": {"<channel> <metric>": flights}},
     "timing": {...}, "wall_s": float | None}

A mean without any value (e.g. RA of a mode none of whose patterns was detected) is None, and
so is its interval.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

SUMMARY_FORMAT = "ema-evaluation-summary/1"
#: model fields copied into the summary (the rest, e.g. the training report, stays out)
_SUMMARY_MODEL_KEYS = ("format", "sha256", "source", "model_id", "training_s",
                       "classifier_accuracy")


def summary_document(result: Mapping[str, Any]) -> dict[str, Any]:
    """The evaluation's figures without per-flight traces or per-pattern prediction lists
    (``summary.json``; shape in the module docstring). Key order is fixed by construction."""
    model = result.get("model") or {}
    return {
        "format": SUMMARY_FORMAT,
        "evaluation_format": result.get("format"),
        "created_at": result.get("created_at"),
        "campaign": result.get("campaign"),
        "model": {k: model[k] for k in _SUMMARY_MODEL_KEYS if k in model},
        "settings": result.get("settings"),
        "detection": result["detection"],
        "classification": result["classification"],
        "prognosis": {m: {k: v for k, v in r.items() if k != "patterns"}
                      for m, r in result["prognosis"].items()},
        "sensors": result.get("sensors"),
        "timing": result.get("timing"),
        "wall_s": result.get("wall_s"),
    }
