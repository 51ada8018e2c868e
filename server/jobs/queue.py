"""The job queue, kept in the ``jobs`` table (durable background work, docs/ARCHITECTURE.md).

Claiming is one atomic ``UPDATE ... WHERE id = (SELECT ... LIMIT 1) RETURNING``: on PostgreSQL the
inner select takes ``FOR UPDATE SKIP LOCKED`` so concurrent workers never wait on each other; on
SQLite the single statement runs under the database's write lock (a stale snapshot makes it fail,
and the claim is simply tried again). A job is eligible when it is queued and due, or running
with an expired lease (its worker died), and no earlier job with the same ``lock_key`` is still
queued or running: one aircraft's flights are analysed in order, one at a time.

Failures are retried with exponential backoff; after ``max_attempts`` the job is ``dead`` and
keeps its last error. A job whose last attempt's worker vanished (killed, out of memory) is not
claimed again once its lease runs out: :func:`bury_abandoned` makes it ``dead``.
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import datetime, timedelta
from typing import Literal, cast

from sqlalchemy import CursorResult, and_, exists, or_, select, update
from sqlalchemy.exc import OperationalError
from sqlalchemy.orm import Session, aliased, sessionmaker

from server.models import Job, utcnow
from server.vocabulary import JobStatus

__all__ = ["RetryPolicy", "claim_next", "complete", "fail", "defer", "renew_lease",
           "bury_abandoned", "ABANDONED", "ClaimedJob"]

ABANDONED = ("The worker running the last attempt stopped without finishing it (killed, out of "
             "memory or lost); its lease ran out.")


@dataclass(frozen=True)
class RetryPolicy:
    """Exponential backoff: ``base_s * 2**(attempt-1)``, capped at ``max_s``."""

    base_s: float = 2.0
    max_s: float = 300.0

    def delay(self, attempt: int) -> timedelta:
        return timedelta(seconds=min(self.max_s, self.base_s * 2 ** max(0, attempt - 1)))


@dataclass(frozen=True)
class ClaimedJob:
    id: int
    kind: str
    flight_id: int | None
    lock_key: str
    attempts: int
    max_attempts: int
    payload: dict


def _eligible(now: datetime, postgres: bool):
    cand, earlier = aliased(Job, name="cand"), aliased(Job, name="earlier")
    query = (
        select(cand.id)
        .where(or_(and_(cand.status == JobStatus.QUEUED, cand.run_after <= now),
                   and_(cand.status == JobStatus.RUNNING, cand.lease_until < now,
                        cand.attempts < cand.max_attempts)))
        .where(~exists().where(earlier.lock_key == cand.lock_key, earlier.id < cand.id,
                               earlier.status.in_((JobStatus.QUEUED, JobStatus.RUNNING))))
        .order_by(cand.id)
        .limit(1)
    )
    if postgres:
        query = query.with_for_update(skip_locked=True)
    return query.scalar_subquery()


def claim_next(factory: sessionmaker[Session], *, worker_id: str, lease_s: float,
               attempts: int = 20) -> ClaimedJob | None:
    """Atomically take the next eligible job, or return None when there is none."""
    for _ in range(attempts):
        session = factory()
        try:
            postgres = session.get_bind().dialect.name == "postgresql"
            now = utcnow()
            stmt = (
                update(Job)
                .where(Job.id == _eligible(now, postgres))
                .values(status=JobStatus.RUNNING, attempts=Job.attempts + 1, locked_by=worker_id,
                        lease_until=now + timedelta(seconds=lease_s), updated_at=now)
                .returning(Job.id, Job.kind, Job.flight_id, Job.lock_key, Job.attempts,
                           Job.max_attempts, Job.payload)
            )
            row = session.execute(stmt).first()
            if row is not None:
                # stamped after the claim saw the previous job of this key finished, so that
                # started_at never precedes that job's finished_at (``now`` above may)
                session.execute(update(Job).where(Job.id == row[0]).values(started_at=utcnow()))
            session.commit()
            return None if row is None else ClaimedJob(*row)
        except OperationalError as exc:
            session.rollback()
            if "locked" not in str(exc).lower() and "snapshot" not in str(exc).lower():
                raise
        finally:
            session.close()
    return None


def renew_lease(session: Session, *, job_id: int, worker_id: str, lease_s: float) -> bool:
    """Extend a lease we still hold; False when the job was taken from us."""
    now = utcnow()
    result = session.execute(update(Job).where(Job.id == job_id, Job.locked_by == worker_id,
                                               Job.status == JobStatus.RUNNING)
                             .values(lease_until=now + timedelta(seconds=lease_s),
                                     updated_at=now))
    return bool(cast(CursorResult, result).rowcount)  # an UPDATE's result has a cursor


def complete(session: Session, *, job_id: int, worker_id: str) -> bool:
    """Mark our job done; False when the lease was lost and another worker owns it now."""
    now = utcnow()
    result = session.execute(update(Job).where(Job.id == job_id, Job.locked_by == worker_id,
                                               Job.status == JobStatus.RUNNING)
                             .values(status=JobStatus.DONE, finished_at=now, updated_at=now,
                                     lease_until=None, last_error=None))
    return bool(cast(CursorResult, result).rowcount)  # an UPDATE's result has a cursor


def fail(session: Session, *, job: ClaimedJob, worker_id: str, error: str,
         policy: RetryPolicy = RetryPolicy()) -> JobStatus | Literal["lost"]:
    """Record a failure: back to ``queued`` after a backoff, or ``dead`` after the last try;
    ``lost`` when another worker holds the job now (nothing recorded)."""
    now = utcnow()
    dead = job.attempts >= job.max_attempts
    values = {"last_error": error[-4000:], "updated_at": now, "lease_until": None,
              "locked_by": None}
    if dead:
        values.update(status=JobStatus.DEAD, finished_at=now)
    else:
        values.update(status=JobStatus.QUEUED, run_after=now + policy.delay(job.attempts))
    result = session.execute(update(Job).where(Job.id == job.id, Job.locked_by == worker_id)
                             .values(**values))
    if not cast(CursorResult, result).rowcount:
        return "lost"
    return JobStatus.DEAD if dead else JobStatus.QUEUED


def bury_abandoned(session: Session, *, limit: int = 20) -> list[ClaimedJob]:
    """Jobs running their last attempt whose lease ran out (the worker vanished) made ``dead``
    with :data:`ABANDONED` as their error, each returned to one caller only: the claim would
    otherwise take them again without end."""
    now = utcnow()
    ids = list(session.scalars(select(Job.id).where(
        Job.status == JobStatus.RUNNING, Job.lease_until < now, Job.attempts >= Job.max_attempts)
        .limit(limit)))
    if not ids:
        return []
    rows = session.execute(
        update(Job).where(Job.id.in_(ids), Job.status == JobStatus.RUNNING, Job.lease_until < now)
        .values(status=JobStatus.DEAD, finished_at=now, updated_at=now, lease_until=None,
                locked_by=None, last_error=ABANDONED)
        .returning(Job.id, Job.kind, Job.flight_id, Job.lock_key, Job.attempts,
                   Job.max_attempts, Job.payload)).all()
    return [ClaimedJob(*row) for row in rows]


def defer(session: Session, *, job: ClaimedJob, worker_id: str, reason: str,
          delay_s: float) -> None:
    """Put a job back without counting the attempt (it could not start, e.g. no model yet)."""
    now = utcnow()
    session.execute(update(Job).where(Job.id == job.id, Job.locked_by == worker_id)
                    .values(status=JobStatus.QUEUED, attempts=Job.attempts - 1, last_error=reason,
                            run_after=now + timedelta(seconds=delay_s), lease_until=None,
                            locked_by=None, updated_at=now))
