"""The worker loop: claim a job, run its handler, record the outcome; renew the lease meanwhile.

``hmsm worker --concurrency N`` starts N of these loops as separate processes (the analysis is
CPU-bound numpy, so processes, not threads). A worker killed mid-job leaves its job ``running``
with a lease that expires; the next claim picks it up again, and every handler is idempotent.
A job given up (``dead``: out of attempts, or its last attempt's worker vanished) runs its
kind's dead letter (``handlers.DEAD_LETTERS``) in the same transaction.
"""

from __future__ import annotations

import logging
import os
import socket
import threading
import traceback
import uuid

from sqlalchemy.orm import Session

from server.blobstore import BlobStore
from server.config import Settings
from server.db import make_engine, make_session_factory
from server.jobs import queue
from server.jobs.context import DeadLetter, Deferred, Handler, JobContext
from server.jobs.handlers import DEAD_LETTERS, HANDLERS
from server.migrate import ensure_schema
from server.vocabulary import JobStatus

__all__ = ["Worker", "run_worker_process"]

log = logging.getLogger("hmsm.worker")


class Worker:
    def __init__(self, settings: Settings, *, lease_s: float = 120.0, poll_s: float = 0.5,
                 handlers: dict[str, Handler] | None = None, worker_id: str | None = None,
                 dead_letters: dict[str, DeadLetter] | None = None):
        self.settings = settings
        self.lease_s = lease_s
        self.poll_s = poll_s
        self.worker_id = worker_id or f"{socket.gethostname()}:{os.getpid()}:{uuid.uuid4().hex[:6]}"
        engine = make_engine(settings.effective_database_url)
        ensure_schema(engine, settings.effective_database_url, auto_upgrade=settings.is_sqlite)
        self.engine = engine
        blobs = BlobStore(settings.blob_dir, settings.tmp_dir)
        blobs.ensure_dirs()
        self.ctx = JobContext(settings, make_session_factory(engine), blobs)
        self.handlers = dict(HANDLERS) if handlers is None else handlers
        self.dead_letters = dict(DEAD_LETTERS) if dead_letters is None else dead_letters

    def _heartbeat(self, job_id: int, done: threading.Event) -> None:
        while not done.wait(self.lease_s / 3):
            with self.ctx.factory() as session:
                if not queue.renew_lease(session, job_id=job_id, worker_id=self.worker_id,
                                         lease_s=self.lease_s):
                    return
                session.commit()

    def _given_up(self, session: Session, job: queue.ClaimedJob, error: str) -> None:
        dead_letter = self.dead_letters.get(job.kind)
        if dead_letter is not None:
            dead_letter(session, job, error)

    def _bury_abandoned(self) -> None:
        with self.ctx.factory() as session:
            for job in queue.bury_abandoned(session):
                log.warning("job %s (%s) abandoned on its last attempt", job.id, job.kind)
                self._given_up(session, job, queue.ABANDONED)
            session.commit()

    def run_once(self) -> bool:
        """Process one job if there is one; return whether a job was claimed."""
        self._bury_abandoned()
        job = queue.claim_next(self.ctx.factory, worker_id=self.worker_id, lease_s=self.lease_s)
        if job is None:
            return False
        done = threading.Event()
        beat = threading.Thread(target=self._heartbeat, args=(job.id, done), daemon=True)
        beat.start()
        try:
            handler = self.handlers.get(job.kind)
            if handler is None:
                raise LookupError(f"no handler for job kind {job.kind!r}")
            handler(self.ctx, job)
        except Exception as exc:
            if isinstance(exc, Deferred):
                with self.ctx.factory() as session:
                    queue.defer(session, job=job, worker_id=self.worker_id, reason=str(exc),
                                delay_s=exc.delay_s)
                    session.commit()
                return True
            error = traceback.format_exc()
            log.warning("job %s (%s) failed on attempt %s", job.id, job.kind, job.attempts)
            with self.ctx.factory() as session:
                outcome = queue.fail(session, job=job, worker_id=self.worker_id, error=error)
                if outcome == JobStatus.DEAD:
                    self._given_up(session, job, error)
                session.commit()
            log.info("job %s -> %s", job.id, outcome)
        else:
            with self.ctx.factory() as session:
                queue.complete(session, job_id=job.id, worker_id=self.worker_id)
                session.commit()
        finally:
            done.set()
            beat.join(timeout=5)
        return True

    def run(self, stop: threading.Event | None = None, *, max_jobs: int | None = None,
            exit_when_idle: bool = False) -> int:
        """Loop until ``stop`` is set (or ``max_jobs`` done, or idle with ``exit_when_idle``)."""
        stop = stop or threading.Event()
        count = 0
        while not stop.is_set() and (max_jobs is None or count < max_jobs):
            if self.run_once():
                count += 1
            elif exit_when_idle:
                break
            else:
                stop.wait(self.poll_s)
        return count


def run_worker_process(settings: Settings, lease_s: float, exit_when_idle: bool) -> None:
    """Entry point of one worker process; SIGTERM finishes the current job, then stops."""
    import signal

    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    worker = Worker(settings, lease_s=lease_s)
    try:
        worker.run(stop, exit_when_idle=exit_when_idle)
    finally:
        worker.engine.dispose()
