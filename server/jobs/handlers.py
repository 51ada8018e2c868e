"""The handler of each job kind, and what to do when one is given up or queued again after a
failed attempt: the registries the worker loop dispatches through."""

from __future__ import annotations

from server.jobs.context import DeadLetter, Handler, RetryNotice
from server.jobs.pipeline import analysis_given_up, analysis_retried, analyze_flight_job
from server.jobs.training_job import train_model_job
from server.models import JobKind

__all__ = ["HANDLERS", "DEAD_LETTERS", "RETRY_NOTICES"]

HANDLERS: dict[str, Handler] = {
    JobKind.ANALYZE_FLIGHT: analyze_flight_job,
    JobKind.TRAIN_MODEL: train_model_job,
}

DEAD_LETTERS: dict[str, DeadLetter] = {
    JobKind.ANALYZE_FLIGHT: analysis_given_up,
}

RETRY_NOTICES: dict[str, RetryNotice] = {
    JobKind.ANALYZE_FLIGHT: analysis_retried,
}
