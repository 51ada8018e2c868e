"""Seconds spent in each named stage of one background job, for the stage-duration histograms
of /metrics (:mod:`server.services.telemetry` stores them; docs/PRODUCTION.md, "Metrics").

A stage is timed around a call (:meth:`StageClock.stage`). The PHM chain runs detection,
classification and prognosis inside one call (``server.phm.chain.run.analyze_flight``), and
that code stays pure numerics that knows nothing of the service; :meth:`StageClock.split`
therefore times the call as a whole and, with a profile hook on the calling thread, the time
spent inside a few watched functions of it, which is set apart as their own stages. The hook
is on only for that call and costs about 0.3 us per Python or C call made inside it (measured:
the chain of 3 actuators over 8 flights took 60 ms instead of 34 ms, against seconds for the
job's decoding and features).
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from types import CodeType, FrameType
from typing import Any

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
    def split(self, rest: str, watched: Mapping[CodeType, str]) -> Iterator[None]:
        """Time the block; the time inside a function whose code is a key of ``watched`` goes
        to that key's stage, the remainder to ``rest``. A watched function called while
        another is running counts for the outer one only, never twice.

        When the thread already has a profile hook (someone profiling the worker), it is left
        alone and nothing of the block is recorded: a wrong split is worse than none."""
        if sys.getprofile() is not None:
            yield
            return
        spent: dict[str, float] = {}
        outer: list[Any] = [None, "", 0.0]  # the watched frame running, its stage, its start

        def hook(frame: FrameType, event: str, _: Any) -> None:
            if event == "call" and outer[0] is None:
                stage = watched.get(frame.f_code)
                if stage is not None:
                    outer[:] = [frame, stage, time.perf_counter()]
            elif event == "return" and frame is outer[0]:  # also on the way out of a raise
                spent[outer[1]] = spent.get(outer[1], 0.0) + time.perf_counter() - outer[2]
                outer[0] = None

        start = time.perf_counter()
        sys.setprofile(hook)
        try:
            yield
        finally:
            sys.setprofile(None)
            total = time.perf_counter() - start
            for stage, seconds in spent.items():
                self.add(stage, seconds)
            self.add(rest, max(0.0, total - sum(spent.values())))
