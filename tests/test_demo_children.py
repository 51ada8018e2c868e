"""The demo's processes are reaped as soon as they end: the background evaluation finishes
minutes into the demo and must not stay a zombie until the demo stops."""

from __future__ import annotations

import os
import sys
import time

import psutil

from server.demo import start_child


def test_a_finished_child_is_reaped_without_anyone_polling_it(tmp_path) -> None:  # type: ignore[no-untyped-def]
    log = tmp_path / "evaluation.log"
    # the evaluation's path: started at low priority, its output in its log
    child = start_child([sys.executable, "-c", "print('evaluated')"], env=dict(os.environ),
                        log=log, nice=True)
    deadline = time.monotonic() + 30
    status = None
    while time.monotonic() < deadline:
        try:
            status = psutil.Process(child.pid).status()
        except psutil.NoSuchProcess:
            break  # exited and reaped: no zombie left behind
        time.sleep(0.05)
    else:
        raise AssertionError(f"child {child.pid} still there after 30 s: {status}")
    assert child.returncode == 0
    assert log.read_text().strip() == "evaluated"
