"""What a job handler is given and may raise: the pieces shared by the worker loop and the
handlers (so that neither imports the other)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

from sqlalchemy.orm import Session, sessionmaker

from server.blobstore import BlobStore
from server.config import Settings
from server.jobs.queue import ClaimedJob
from server.timing import StageClock

__all__ = ["JobContext", "Handler", "DeadLetter", "RetryNotice", "Deferred"]


@dataclass
class JobContext:
    settings: Settings
    factory: sessionmaker[Session]
    blobs: BlobStore
    #: this job's stage timings (the worker gives each job a fresh clock and stores them)
    stages: StageClock = field(default_factory=StageClock)


Handler = Callable[[JobContext, ClaimedJob], None]
#: what to do when a job of a kind is given up (``dead``): given the session that records it,
#: the job and its last error; it flushes, the worker commits both together
DeadLetter = Callable[[Session, ClaimedJob, str], None]
#: what to do when an attempt of a job of a kind failed and it is queued again: the same
#: arguments as a dead letter (the failed attempt is ``job.attempts``)
RetryNotice = Callable[[Session, ClaimedJob, str], None]


class Deferred(Exception):
    """Raised by a handler that cannot run yet: requeue after ``delay_s``, no attempt used."""

    def __init__(self, reason: str, delay_s: float = 30.0):
        super().__init__(reason)
        self.delay_s = delay_s
