"""While the demo's background evaluation runs, the evaluation page says what it is doing and
how far it is, from the status file the evaluation writes (server/demo_evaluation.py)."""

from __future__ import annotations

import json
import threading
import time
from pathlib import Path

from server.demo_evaluation import watch_campaign
from server.services.evaluation_status import read_progress, write_progress
from tests.web.test_pages import sign_in

SIMULATING = "simulating the verification campaign (quick, seed 2, 10 aircraft unseen in design)"


def test_page_shows_the_stage_and_its_progress_from_the_status_file(client, keys, app) -> None:  # type: ignore[no-untyped-def]
    sign_in(client, keys["viewer"])
    evaluation = Path(app.state.settings.data_dir) / "evaluation"
    page = client.get("/evaluation").text
    assert 'id="running"' not in page and 'http-equiv="refresh"' not in page

    write_progress(evaluation, {"stage": SIMULATING, "done": 12, "total": 31,
                                "unit": "patterns", "since": time.time() - 125})
    page = client.get("/evaluation").text
    assert f"{SIMULATING}: 12 of 31 patterns" in page
    assert "(for 2 min so far)" in page and 'http-equiv="refresh" content="20"' in page

    write_progress(evaluation, {"stage": "scoring model version 3 on it", "done": 30,
                                "total": 31, "unit": "patterns", "since": time.time()})
    assert "scoring model version 3 on it: 30 of 31 patterns" in client.get("/evaluation").text

    # a status without counts (or with nonsense ones) still names its stage
    write_progress(evaluation, {"stage": "starting", "done": True, "total": 31})
    page = client.get("/evaluation").text
    assert '<span id="running-stage">starting</span>' in page

    (evaluation / "latest.json").write_text(json.dumps({"prognosis": {}}))
    page = client.get("/evaluation").text
    assert 'id="running"' not in page and 'http-equiv="refresh"' not in page


def test_the_campaigns_finished_patterns_are_reported_while_it_runs(tmp_path) -> None:  # type: ignore[no-untyped-def]
    campaign, evaluation = tmp_path / "campaign", tmp_path / "evaluation"
    progress = campaign / "progress"
    progress.mkdir(parents=True)
    (progress / "settings.json").write_text("{}")  # the run's settings: not a pattern
    for n in range(12):
        (progress / f"{n:04d}.json").write_text("{}")
    seen: list[tuple[int, int]] = []

    def report(done: int, total: int) -> None:
        seen.append((done, total))
        write_progress(evaluation, {"stage": "simulating", "done": done, "total": total})

    stop = threading.Event()
    watcher = watch_campaign(campaign, 31, report, stop, every_s=0.05)
    _until(lambda: (12, 31) in seen)
    for n in range(12, 20):
        (progress / f"{n:04d}.json").write_text("{}")
    _until(lambda: seen[-1] == (20, 31))
    (campaign / "manifest.json").write_text("{}")  # finished: the store is then removed
    for path in progress.iterdir():
        path.unlink()
    _until(lambda: seen[-1] == (31, 31))
    stop.set()
    watcher.join(timeout=5)
    assert not watcher.is_alive()
    assert read_progress(evaluation) == {"stage": "simulating", "done": 31, "total": 31}


def _until(condition, timeout_s: float = 10.0) -> None:  # type: ignore[no-untyped-def]
    deadline = time.monotonic() + timeout_s
    while not condition():
        assert time.monotonic() < deadline, "not reported in time"
        time.sleep(0.02)
