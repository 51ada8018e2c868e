"""The worker loop: claim a job, run its handler, record the outcome; renew the lease meanwhile.

``hmsm worker --concurrency N`` starts N of these loops as separate processes (the analysis is
CPU-bound numpy, so processes, not threads). A worker killed mid-job leaves its job ``running``
with a lease that expires; the next claim picks it up again, and every handler is idempotent.
A job given up (``dead``: out of attempts, or its last attempt's worker vanished) runs its
kind's dead letter (``handlers.DEAD_LETTERS``) in the same transaction; a failed attempt that
is queued again, its kind's retry notice (``handlers.RETRY_NOTICES``).

What a worker measures reaches the API's /metrics through the database
(:mod:`server.services.telemetry`): each attempt's outcome, a finished job's duration and its
stages', and a heartbeat every ``beat_s`` while :meth:`Worker.run` loops. They are written in
transactions of their own, after the job's: a failure to record them is logged and never
fails, repeats or delays a job.
"""

from __future__ import annotations

import dataclasses
import logging
import os
import socket
import threading
import time
import traceback
import uuid
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from datetime import timedelta

from sqlalchemy.orm import Session

from server.blobstore_factory import open_blob_store
from server.config import Settings
from server.db import make_engine, make_session_factory
from server.jobs import queue
from server.jobs.context import DeadLetter, Deferred, Handler, JobContext, RetryNotice
from server.jobs.handlers import DEAD_LETTERS, HANDLERS, RETRY_NOTICES
from server.migrate import ensure_schema
from server.models import utcnow
from server.services import retention, telemetry
from server.timing import StageClock
from server.vocabulary import JobStatus

__all__ = ["Worker", "run_worker_process"]

log = logging.getLogger("hmsm.worker")

#: a worker silent this long is forgotten (its heartbeat row removed) by the next to start
FORGET_SILENT_AFTER = timedelta(days=1)


class Worker:
    def __init__(self, settings: Settings, *, lease_s: float = 120.0, poll_s: float = 0.5,
                 handlers: dict[str, Handler] | None = None, worker_id: str | None = None,
                 dead_letters: dict[str, DeadLetter] | None = None, beat_s: float = 10.0,
                 retry_notices: dict[str, RetryNotice] | None = None):
        self.settings = settings
        self.lease_s = lease_s
        self.poll_s = poll_s
        self.beat_s = beat_s
        self.worker_id = worker_id or f"{socket.gethostname()}:{os.getpid()}:{uuid.uuid4().hex[:6]}"
        self.started_at = utcnow()
        self._job_id: int | None = None  # the job running now, for the heartbeat
        engine = make_engine(settings.effective_database_url)
        ensure_schema(engine, settings.effective_database_url, auto_upgrade=settings.is_sqlite)
        self.engine = engine
        self.ctx = JobContext(settings, make_session_factory(engine), open_blob_store(settings))
        self.handlers = dict(HANDLERS) if handlers is None else handlers
        self.dead_letters = dict(DEAD_LETTERS) if dead_letters is None else dead_letters
        self.retry_notices = dict(RETRY_NOTICES) if retry_notices is None else retry_notices

    def _heartbeat(self, job_id: int, done: threading.Event) -> None:
        while not done.wait(self.lease_s / 3):
            with self.ctx.factory() as session:
                if not queue.renew_lease(session, job_id=job_id, worker_id=self.worker_id,
                                         lease_s=self.lease_s):
                    return
                session.commit()

    def _record(self, what: str, write: Callable[[Session], object]) -> None:
        """Telemetry in a transaction of its own; a failure is logged, never raised."""
        try:
            with self.ctx.factory() as session:
                write(session)
                session.commit()
        except Exception:
            log.warning("could not record %s for /metrics", what, exc_info=True)

    def _attempt(self, job: queue.ClaimedJob, outcome: str, seconds: float | None = None,
                 stages: dict[str, float] | None = None) -> None:
        self._record(f"job {job.id} ({outcome})", lambda s: telemetry.record_attempt(
            s, kind=job.kind, outcome=outcome, seconds=seconds, stages=stages))

    def beat(self) -> None:
        """This worker's heartbeat row brought up to now, with the job it runs."""
        self._record("the heartbeat", lambda s: telemetry.beat(
            s, worker_id=self.worker_id, host=socket.gethostname(), pid=os.getpid(),
            started_at=self.started_at, job_id=self._job_id))

    @contextmanager
    def _beating(self, stop: threading.Event) -> Iterator[None]:
        """Heartbeats every ``beat_s`` on a thread of their own (a job may run for minutes),
        from now until the block ends; then the row is removed: only a worker that died
        leaves a heartbeat ageing."""
        self._record("forgetting silent workers", lambda s: telemetry.forget_silent_workers(
            s, silent_for=FORGET_SILENT_AFTER))
        self.beat()
        done = threading.Event()

        def loop() -> None:
            while not done.wait(self.beat_s) and not stop.is_set():
                self.beat()

        thread = threading.Thread(target=loop, name="hmsm-heartbeat", daemon=True)
        thread.start()
        try:
            yield
        finally:
            done.set()
            thread.join(timeout=5)
            self._record("the worker's end", lambda s: telemetry.forget_worker(
                s, worker_id=self.worker_id))

    def _given_up(self, session: Session, job: queue.ClaimedJob, error: str) -> None:
        dead_letter = self.dead_letters.get(job.kind)
        if dead_letter is not None:
            dead_letter(session, job, error)

    def _bury_abandoned(self) -> None:
        with self.ctx.factory() as session:
            buried = queue.bury_abandoned(session)
            for job in buried:
                log.warning("job %s (%s) abandoned on its last attempt", job.id, job.kind)
                self._given_up(session, job, queue.ABANDONED)
            session.commit()
        for job in buried:
            self._attempt(job, "abandoned")

    def run_once(self) -> bool:
        """Process one job if there is one; return whether a job was claimed."""
        self._bury_abandoned()
        job = queue.claim_next(self.ctx.factory, worker_id=self.worker_id, lease_s=self.lease_s)
        if job is None:
            return False
        done = threading.Event()
        beat = threading.Thread(target=self._heartbeat, args=(job.id, done), daemon=True)
        beat.start()
        self._job_id = job.id
        ctx = dataclasses.replace(self.ctx, stages=StageClock())  # this job's own timings
        start = time.perf_counter()
        try:
            handler = self.handlers.get(job.kind)
            if handler is None:
                raise LookupError(f"no handler for job kind {job.kind!r}")
            handler(ctx, job)
        except Exception as exc:
            if isinstance(exc, Deferred):
                with self.ctx.factory() as session:
                    queue.defer(session, job=job, worker_id=self.worker_id, reason=str(exc),
                                delay_s=exc.delay_s)
                    session.commit()
                self._attempt(job, "deferred")
                return True
            error = traceback.format_exc()
            log.warning("job %s (%s) failed on attempt %s", job.id, job.kind, job.attempts)
            with self.ctx.factory() as session:
                outcome = queue.fail(session, job=job, worker_id=self.worker_id, error=error)
                if outcome == JobStatus.DEAD:
                    self._given_up(session, job, error)
                elif outcome == JobStatus.QUEUED and job.kind in self.retry_notices:
                    self.retry_notices[job.kind](session, job, error)
                session.commit()
            log.info("job %s -> %s", job.id, outcome)
            if outcome != "lost":  # lost: another worker holds it now and will count it
                self._attempt(job, "dead" if outcome == JobStatus.DEAD else "retried")
        else:
            with self.ctx.factory() as session:
                completed = queue.complete(session, job_id=job.id, worker_id=self.worker_id)
                session.commit()
            if completed:
                self._attempt(job, "done", time.perf_counter() - start, ctx.stages.seconds)
        finally:
            self._job_id = None
            done.set()
            beat.join(timeout=5)
        return True

    def sweep_orphans(self) -> None:
        """Blobs no row keeps, left by a delete that failed or a crash (retention's
        sweep_orphans); a store not answering now is left for the next start."""
        try:
            with self.ctx.factory() as session:
                removed = retention.sweep_orphans(session=session, blobs=self.ctx.blobs)
        except OSError as exc:
            log.warning("could not sweep orphan blobs: %s", exc)
            return
        if removed:
            log.info("removed %d orphan blobs", removed)

    def run(self, stop: threading.Event | None = None, *, max_jobs: int | None = None,
            exit_when_idle: bool = False) -> int:
        """Loop until ``stop`` is set (or ``max_jobs`` done, or idle with ``exit_when_idle``)."""
        stop = stop or threading.Event()
        count = 0
        self.sweep_orphans()
        with self._beating(stop):
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
