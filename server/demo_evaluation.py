"""The demo's background evaluation: a small verification campaign, then the active model
evaluated on it, which fills the dashboard's evaluation page (``python -m
server.demo_evaluation``, started by ``hmsm demo`` at low priority).

Resumable: the campaign resumes where it stopped (a finished pattern is never simulated
again), and nothing runs when ``evaluation/latest.json`` exists already. While it runs,
``evaluation/demo-progress.json`` says what it is doing, for the evaluation page
(:mod:`server.services.evaluation_status`).
"""

from __future__ import annotations

import sys
import time

from server.config import load_settings
from server.services.evaluation_status import clear_progress, write_progress

__all__ = ["VERIFICATION_SEED", "main"]

VERIFICATION_SEED = 2


def main(argv: list[str] | None = None) -> int:
    from server.cli import main as hmsm
    from server.db import make_engine, make_session_factory
    from server.services import models as model_service

    settings = load_settings()
    evaluation_dir = settings.data_dir / "evaluation"
    if (evaluation_dir / "latest.json").exists():
        return 0
    started = time.time()
    campaign = model_service.campaign_dir(settings.data_dir, "demo-verification")
    write_progress(evaluation_dir, {"stage": "simulating a quick verification campaign (seed "
                      f"{VERIFICATION_SEED}, 10 aircraft unseen in design)", "since": started})
    # streamed: every flight's features kept, its log only for a sample (a few MB, not 1 GB)
    code = hmsm(["campaign", "--kind", "verification", "--seed", str(VERIFICATION_SEED),
                 "--scale", "quick", "--out", str(campaign), "--keep-raw-every", "200",
                 "--workers", "1", "--no-progress"])
    if code != 0:
        clear_progress(evaluation_dir)
        return code
    engine = make_engine(settings.effective_database_url)
    with make_session_factory(engine)() as session:
        active = model_service.active_version(session=session)
        model_id = None if active is None else active.id
    engine.dispose()
    if model_id is None:
        clear_progress(evaluation_dir)
        print("demo evaluation: no active model", file=sys.stderr)
        return 1
    write_progress(evaluation_dir, {"stage": f"evaluating model version {model_id} on it",
                      "since": time.time(), "started": started})
    try:
        return hmsm(["evaluate", "--campaign", str(campaign), "--model-id", str(model_id),
                     "--jobs", "1", "--no-progress", "--timing-flights", "0"])
    finally:
        clear_progress(evaluation_dir)


if __name__ == "__main__":
    sys.exit(main())
