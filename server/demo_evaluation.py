"""The demo's background evaluation: a small verification campaign, then the active model
evaluated on it, which fills the dashboard's evaluation page (``python -m
server.demo_evaluation``, started by ``hmsm demo`` at low priority).

Resumable: the campaign resumes where it stopped (a finished pattern is never simulated
again), and nothing runs when ``evaluation/latest.json`` exists already. While it runs,
``evaluation/demo-progress.json`` says what it is doing and how far it is (patterns
simulated, then patterns scored, of the campaign's 31), for the evaluation page
(:mod:`server.services.evaluation_status`).
"""

from __future__ import annotations

import argparse
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path

from server.config import Settings, load_settings
from server.services.evaluation_status import clear_progress, write_progress

__all__ = ["VERIFICATION_SEED", "main", "finished_patterns", "watch_campaign"]

VERIFICATION_SEED = 2
#: how often the simulation's progress is written while the campaign runs [s]
WATCH_S = 2.0


def finished_patterns(campaign: Path, total: int) -> int:
    """Patterns of a campaign run that are done: one file each in ``DIR/progress/`` while it
    runs (the simulator's resumable store), all ``total`` once its manifest is written."""
    if (campaign / "manifest.json").exists():
        return total
    return min(total, sum(1 for _ in (campaign / "progress").glob("[0-9][0-9][0-9][0-9].json")))


def watch_campaign(campaign: Path, total: int, report: Callable[[int, int], None],
                   stop: threading.Event, every_s: float = WATCH_S) -> threading.Thread:
    """A thread calling ``report(done, total)`` with the campaign's finished patterns now and
    every ``every_s`` until ``stop`` is set."""
    def run() -> None:
        while True:
            report(finished_patterns(campaign, total), total)
            if stop.wait(every_s):
                return

    thread = threading.Thread(target=run, name="campaign-progress", daemon=True)
    thread.start()
    return thread


def main(argv: list[str] | None = None) -> int:
    settings = load_settings()
    evaluation_dir = settings.data_dir / "evaluation"
    if (evaluation_dir / "latest.json").exists():
        return 0
    try:
        return _evaluate(settings, evaluation_dir)
    finally:
        clear_progress(evaluation_dir)  # however it ends: the page must not show it running


def _evaluate(settings: Settings, evaluation_dir: Path) -> int:
    from server.cli import main as hmsm
    from server.db import make_engine, make_session_factory
    from server.evaluation.cli import add_evaluate_arguments, run_evaluate
    from server.services import models as model_service
    from sim_worker.campaign import plan_campaign

    started = time.time()
    campaign = model_service.campaign_dir(settings.data_dir, "demo-verification")

    def status(stage: str, done: int, total: int) -> None:
        write_progress(evaluation_dir, {"stage": stage, "done": done, "total": total,
                                        "unit": "patterns", "since": started})

    patterns = len(plan_campaign("verification", VERIFICATION_SEED, "quick"))
    simulating = (f"simulating the verification campaign (quick, seed {VERIFICATION_SEED}, "
                  "10 aircraft unseen in design)")
    stop = threading.Event()
    watcher = watch_campaign(campaign, patterns,
                             lambda done, total: status(simulating, done, total), stop)
    # streamed: every flight's features kept, its log only for a sample (a few MB, not 1 GB)
    try:
        code = hmsm(["campaign", "--kind", "verification", "--seed", str(VERIFICATION_SEED),
                     "--scale", "quick", "--out", str(campaign), "--keep-raw-every", "200",
                     "--workers", "1", "--no-progress"])
    finally:
        stop.set()
        watcher.join()
    if code != 0:
        return code
    engine = make_engine(settings.effective_database_url)
    with make_session_factory(engine)() as session:
        active = model_service.active_version(session=session)
        model_id = None if active is None else active.id
    engine.dispose()
    if model_id is None:
        print("demo evaluation: no active model", file=sys.stderr)
        return 1
    scoring = f"scoring model version {model_id} on it"
    status(scoring, 0, patterns)
    args = add_evaluate_arguments(argparse.ArgumentParser()).parse_args(
        ["--campaign", str(campaign), "--model-id", str(model_id), "--jobs", "1",
         "--no-progress", "--timing-flights", "0"])
    return run_evaluate(args, settings,
                        progress=lambda done, total: status(scoring, done, total))


if __name__ == "__main__":
    sys.exit(main())
