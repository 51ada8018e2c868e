"""What a background evaluation is doing (``<data_dir>/evaluation/demo-progress.json``): written
by the demo's background evaluation (:mod:`server.demo_evaluation`), read by the evaluation
page while ``latest.json`` does not exist yet.

The document: ``{"stage": str, "done": int, "total": int, "unit": "patterns", "since":
seconds since the epoch}`` (the page shows "stage: done of total unit, for N min"); written
whole to a temporary file that then replaces it, so a reader never sees half of one."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

__all__ = ["PROGRESS_FILE", "read_progress", "write_progress", "clear_progress"]

PROGRESS_FILE = "demo-progress.json"


def write_progress(evaluation_dir: Path, doc: dict[str, Any]) -> None:
    evaluation_dir.mkdir(parents=True, exist_ok=True)
    tmp = evaluation_dir / (PROGRESS_FILE + ".tmp")
    tmp.write_text(json.dumps(doc))
    tmp.replace(evaluation_dir / PROGRESS_FILE)


def clear_progress(evaluation_dir: Path) -> None:
    (evaluation_dir / PROGRESS_FILE).unlink(missing_ok=True)


def read_progress(evaluation_dir: Path) -> dict[str, Any] | None:
    """What the background evaluation is doing, or None when none runs."""
    try:
        return dict(json.loads((evaluation_dir / PROGRESS_FILE).read_text()))
    except (OSError, ValueError, TypeError):
        return None
