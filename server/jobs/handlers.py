"""The handler of each job kind: the one registry the worker loop dispatches through."""

from __future__ import annotations

from server.jobs.context import Handler
from server.jobs.pipeline import analyze_flight_job
from server.jobs.training_job import train_model_job
from server.models import JobKind

__all__ = ["HANDLERS"]

HANDLERS: dict[str, Handler] = {
    JobKind.ANALYZE_FLIGHT: analyze_flight_job,
    JobKind.TRAIN_MODEL: train_model_job,
}
