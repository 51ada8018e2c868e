"""Seconds spent in each named stage of one background job, for the stage-duration histograms
of /metrics (:mod:`server.services.telemetry` stores them; docs/PRODUCTION.md, "Metrics").

A stage is timed around a call (:meth:`StageClock.stage`). The PHM chain runs detection,
classification and prognosis inside one call (``server.phm.chain.run.analyze_flight``), which
times its classification and prognosis itself when given ``stage=clock.stage``;
:meth:`StageClock.rest` times the call and counts the rest as detection.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator
from contextlib import contextmanager

__all__ = ["StageClock"]


class StageClock:
    """Seconds by stage name, added up over one job (a stage run several times adds up)."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = {}

    def add(self, stage: str, seconds: float) -> None:
        if not math.isfinite(seconds) or seconds < 0:
            raise ValueError(f"a stage takes a finite, non-negative time, not {seconds!r}")
        self.seconds[stage] = self.seconds.get(stage, 0.0) + seconds

    @contextmanager
    def stage(self, name: str) -> Iterator[None]:
        """Time the block as ``name`` (also when it raises: the worker keeps the timings of
        finished jobs only)."""
        start = time.perf_counter()
        try:
            yield
        finally:
            self.add(name, time.perf_counter() - start)

    @contextmanager
    def rest(self, name: str) -> Iterator[None]:
        """Time the block as ``name``, less the time of the stages timed inside it: the
        chain's call is detection but for the classification and prognosis it times itself
        (``analyze_flight(..., stage=clock.stage)``)."""
        before = sum(self.seconds.values())
        start = time.perf_counter()
        try:
            yield
        finally:
            inside = sum(self.seconds.values()) - before
            self.add(name, max(0.0, time.perf_counter() - start - inside))
