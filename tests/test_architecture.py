"""The layer contracts of ``pyproject.toml`` (``[tool.importlinter]``), checked on every run:
API, dashboard and jobs go through the services, and neither the API routes nor the dashboard
import SQLAlchemy; the PHM chain and the simulator import nothing of the service; the
flight-log contract and the vocabulary stand alone; the blob stores sit below the factory
that chooses between them (no import circle)."""

from __future__ import annotations

import subprocess
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_import_contracts_are_kept() -> None:
    lint = Path(sys.executable).with_name("lint-imports")
    result = subprocess.run([str(lint), "--no-cache"], cwd=ROOT, capture_output=True,
                            text=True, timeout=300)
    assert result.returncode == 0, result.stdout[-4000:] + result.stderr[-2000:]
    # every contract of pyproject.toml was checked (none skipped, none left out of the count)
    contracts = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["importlinter"][
        "contracts"]
    names = {c["name"] for c in contracts}
    assert "The dashboard queries the database only through the services" in names
    assert len(contracts) == 7
    assert f"{len(contracts)} kept, 0 broken" in result.stdout


def test_the_code_is_lint_clean() -> None:
    """Ruff (configured in ``pyproject.toml``) on everything: the suite, and so CI, enforces
    it rather than leaving it to whoever remembers to run it."""
    ruff = Path(sys.executable).with_name("ruff")
    result = subprocess.run([str(ruff), "check", "--no-cache", "."], cwd=ROOT,
                            capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stdout[-4000:] + result.stderr[-2000:]
