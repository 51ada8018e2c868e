"""Checks of external input and state that must hold under ``python -O`` too (which strips
``assert`` statements): each raises a ValueError or RuntimeError that says what is wrong."""

from __future__ import annotations

from typing import Any

import pytest

import server.migrate
from server.evaluation import runner
from server.jobs.pipeline import analyze_flight_job
from server.jobs.queue import ClaimedJob
from sim_worker.campaign import PatternSpec
from sim_worker.campaign.pattern import _constant_run, _fault_to_failure


def test_an_analysis_job_without_a_flight_is_an_error() -> None:
    job = ClaimedJob(id=7, kind="analyze_flight", flight_id=None, lock_key="x", attempts=1,
                     max_attempts=3, payload={})
    with pytest.raises(ValueError, match="job 7 names no flight"):
        analyze_flight_job(None, job)  # type: ignore[arg-type]  # fails before using it


def test_an_evaluation_worker_without_its_model_is_an_error(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    monkeypatch.setattr(runner, "_WORKER_MODEL", None)
    with pytest.raises(RuntimeError, match="no model"):
        runner._work(None)  # type: ignore[arg-type]


def test_a_migrations_directory_without_a_head_is_an_error(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    class NoHead:
        def get_current_head(self) -> None:
            return None

    monkeypatch.setattr(server.migrate.ScriptDirectory, "from_config",
                        staticmethod(lambda cfg: NoHead()))
    with pytest.raises(RuntimeError, match="no Alembic revision"):
        server.migrate.head_revision()


@pytest.mark.parametrize("mode", ["BDO", "MTWEAR"])
def test_a_fault_pattern_without_a_position_is_an_error(mode: str) -> None:
    spec = PatternSpec("X-01", 0, 0, mode, None, 10, 2, 1, 0.0)

    def render(fault: Any, index: int) -> Any:
        raise AssertionError("nothing is rendered")

    with pytest.raises(ValueError, match=f"a {mode} pattern needs a position"):
        if mode == "BDO":  # a priori
            next(_constant_run(spec, render))
        else:
            next(_fault_to_failure(None, spec, None, render))  # type: ignore[arg-type]
