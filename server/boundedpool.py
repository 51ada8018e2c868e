"""A few threads of its own for heavy reads, with a bounded wait: :class:`BoundedPool`.

A request that decodes a flight log holds its batch, arrays and response at once; twenty at a
time on the server's general thread pool held twenty of them, and each thread's malloc arena
kept its share afterwards (docs/SECURITY.md, "Hostile uploads"). On a pool of ``workers``
threads at most that many run, and only their arenas fill.
"""

from __future__ import annotations

import asyncio
import functools
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from typing import Any, TypeVar

from server.errors import ServiceUnavailable

__all__ = ["BoundedPool"]

T = TypeVar("T")


class BoundedPool:
    """Runs blocking calls on ``workers`` threads; up to ``waiting`` more calls wait their turn,
    past that a call is refused at once with 503 ``busy`` and ``Retry-After``."""

    def __init__(self, name: str, workers: int, waiting: int, retry_after_s: int = 2):
        self._executor = ThreadPoolExecutor(workers, thread_name_prefix=f"hmsm-{name}")
        self._slots = workers + waiting
        self._taken = 0  # only touched on the event loop
        self._retry_after = str(retry_after_s)

    async def run(self, fn: Callable[..., T], /, *args: Any, **kwargs: Any) -> T:
        if self._taken >= self._slots:
            raise ServiceUnavailable(
                "Too many of these requests at once; try again shortly.", code="busy",
                details={"running_or_waiting": self._taken},
                headers={"Retry-After": self._retry_after})
        self._taken += 1
        try:  # a waiting call whose request is cancelled leaves the queue with it
            return await asyncio.get_running_loop().run_in_executor(
                self._executor, functools.partial(fn, *args, **kwargs))
        finally:
            self._taken -= 1

    def shutdown(self) -> None:
        self._executor.shutdown(wait=False, cancel_futures=True)
