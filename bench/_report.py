"""Shared by the benchmarks: the machine they ran on, and their block of docs/BENCHMARKS.md."""

from __future__ import annotations

import platform
import re
from pathlib import Path

__all__ = ["BENCHMARKS", "cpu_model", "replace_block"]

BENCHMARKS = Path(__file__).resolve().parents[1] / "docs" / "BENCHMARKS.md"


def cpu_model() -> str:
    """CPU model name from /proc/cpuinfo (or what platform knows)."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def replace_block(start: str, end: str, text: str, doc: Path = BENCHMARKS) -> None:
    """Put ``text`` between the ``start`` and ``end`` markers of ``doc`` (appended if absent);
    the other benchmarks' blocks are left as they are."""
    block = f"{start}\n{text.strip()}\n{end}"
    current = doc.read_text() if doc.exists() else "# Benchmarks\n"
    if start in current and end in current:
        current = re.sub(re.escape(start) + r".*?" + re.escape(end), lambda _m: block, current,
                         flags=re.S)
    else:
        current = current.rstrip() + "\n\n" + block + "\n"
    doc.parent.mkdir(parents=True, exist_ok=True)
    doc.write_text(current)
