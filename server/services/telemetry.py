"""The workers' telemetry in the database, and what /metrics reads of it at scrape time.

Workers are separate processes, possibly on other hosts with no filesystem in common with the
API, so a worker's measurements go where both meet: the database. Each finished job adds its
duration and its stages' durations to a histogram kept as bucket counters (``job_timings``:
kinds x stages x buckets rows, however many jobs ran), each attempt's outcome to a counter
(``job_attempts``), and every worker upserts its heartbeat (``worker_heartbeats``). At scrape
the API reads those small tables and counts the queue (:func:`snapshot`): a scrape costs a
handful of indexed queries whatever the history, and any API process (on any host) reports
the same figures.

Increments are ``INSERT .. ON CONFLICT DO UPDATE SET n = n + excluded.n``, atomic on both
PostgreSQL and SQLite, written in one order (sorted keys) so that two workers' transactions
never wait on each other in a cycle.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from datetime import datetime, timedelta, timezone
from typing import Any, cast

from sqlalchemy import CursorResult, delete, func, select
from sqlalchemy.dialects import postgresql, sqlite
from sqlalchemy.orm import Session

from server.models import Job, JobAttempts, JobKind, JobTiming, WorkerHeartbeat, utcnow
from server.vocabulary import JobStatus

__all__ = ["BUCKETS_S", "JOB", "STAGES", "OUTCOMES", "record_attempt", "beat", "forget_worker",
           "forget_silent_workers", "snapshot", "Histogram", "WorkerBeat", "Telemetry"]

#: upper bounds of the duration buckets [s]: a classification takes milliseconds, a flight's
#: features seconds, a training job up to an hour
BUCKETS_S = (0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0, 10.0,
             30.0, 60.0, 120.0, 300.0, 600.0, 1800.0, 3600.0)
#: the stage name of a whole attempt, beside the stages of an analysis
JOB = "job"
#: the stages of an analysis (server/jobs/pipeline.py): in this order in a job
STAGES = ("decode", "features", "detection", "classification", "prognosis")
#: how an attempt ended: done; failed and queued again (retried) or given up (dead); put back
#: without counting (deferred, e.g. no model yet); its worker vanished on the last attempt
#: (abandoned, buried by another worker)
OUTCOMES = ("done", "retried", "dead", "deferred", "abandoned")
_INF = "+Inf"
_LE = [repr(b) for b in BUCKETS_S] + [_INF]


def _bucket_of(seconds: float) -> str:
    """The label of the smallest bucket holding ``seconds``."""
    return next((repr(b) for b in BUCKETS_S if seconds <= b), _INF)


def _upsert(session: Session, table: Any, keys: dict[str, Any], adds: dict[str, Any]) -> None:
    """``keys``' row with ``adds`` added to its columns (created with them if absent)."""
    dialect = session.get_bind().dialect.name
    insert = postgresql.insert if dialect == "postgresql" else sqlite.insert
    stmt = insert(table).values(**keys, **adds)
    stmt = stmt.on_conflict_do_update(
        index_elements=list(keys),
        set_={name: getattr(table, name) + getattr(stmt.excluded, name) for name in adds})
    session.execute(stmt)


def _check_kind(kind: str) -> None:
    if kind not in set(JobKind):
        raise ValueError(f"unknown job kind {kind!r}")


def _check_seconds(stage: str, seconds: float) -> None:
    if stage != JOB and stage not in STAGES:
        raise ValueError(f"unknown stage {stage!r}")
    if not math.isfinite(seconds) or seconds < 0:
        raise ValueError(f"stage {stage!r}: a duration is finite and non-negative")


def record_attempt(session: Session, *, kind: str, outcome: str, seconds: float | None = None,
                   stages: Mapping[str, float] | None = None) -> None:
    """Count one attempt of a ``kind`` job that ended with ``outcome``; a finished one (done)
    also adds its duration and its stages' to the histograms. Flushes; the caller commits."""
    _check_kind(kind)
    if outcome not in OUTCOMES:
        raise ValueError(f"unknown outcome {outcome!r}")
    timings = dict(stages or {})
    if seconds is not None:
        timings[JOB] = seconds
    for stage, value in timings.items():
        _check_seconds(stage, value)
    for stage, value in sorted(timings.items()):  # one order: no lock cycle between workers
        _upsert(session, JobTiming, {"kind": kind, "stage": stage, "le": _bucket_of(value)},
                {"observations": 1, "seconds": float(value)})
    _upsert(session, JobAttempts, {"kind": kind, "outcome": outcome}, {"attempts": 1})
    session.flush()


def beat(session: Session, *, worker_id: str, host: str, pid: int, started_at: datetime,
         job_id: int | None) -> None:
    """The worker's sign of life: its row created or brought up to now."""
    now = utcnow()
    row = session.get(WorkerHeartbeat, worker_id)
    if row is None:
        session.add(WorkerHeartbeat(worker_id=worker_id, host=host[:255], pid=pid,
                                    started_at=started_at, beat_at=now, job_id=job_id))
    else:
        row.beat_at, row.job_id = now, job_id
    session.flush()


def forget_worker(session: Session, *, worker_id: str) -> None:
    """A worker that stops cleanly leaves no heartbeat to age (only a dead one should)."""
    session.execute(delete(WorkerHeartbeat).where(WorkerHeartbeat.worker_id == worker_id))


def forget_silent_workers(session: Session, *, silent_for: timedelta) -> int:
    """Remove the rows of workers silent for longer than ``silent_for`` (each restart is a new
    worker id: without this the label set of /metrics would only grow); return how many."""
    result = session.execute(delete(WorkerHeartbeat).where(
        WorkerHeartbeat.beat_at < utcnow() - silent_for))
    return int(cast(CursorResult, result).rowcount or 0)  # a DELETE's result has a cursor


@dataclass(frozen=True)
class Histogram:
    """Cumulative bucket counts (``(le, count)``, ending with ``+Inf``), their sum and count."""

    buckets: list[tuple[str, int]]
    sum_s: float

    @property
    def count(self) -> int:
        return self.buckets[-1][1]


@dataclass(frozen=True)
class WorkerBeat:
    worker_id: str
    host: str
    pid: int
    started_at: datetime
    beat_at: datetime
    job_id: int | None


@dataclass
class Telemetry:
    """What /metrics shows of the queue and the workers, read in one scrape."""

    queue_depth: dict[str, int] = field(default_factory=dict)
    oldest_queued_s: dict[str, float] = field(default_factory=dict)
    #: (kind, status) -> jobs, for the statuses that stay small: queued, running, dead
    jobs: dict[tuple[str, str], int] = field(default_factory=dict)
    #: (kind, stage) -> histogram; stage JOB is the whole attempt
    timings: dict[tuple[str, str], Histogram] = field(default_factory=dict)
    attempts: dict[tuple[str, str], int] = field(default_factory=dict)
    workers: list[WorkerBeat] = field(default_factory=list)


_COUNTED = (JobStatus.QUEUED, JobStatus.RUNNING, JobStatus.DEAD)


def snapshot(session: Session) -> Telemetry:
    """The queue counted (statuses other than ``done``, which grows with every flight, read
    through the claim index) and the workers' tables read."""
    now = utcnow()
    out = Telemetry()
    for kind in JobKind:
        out.queue_depth[kind] = 0
        out.oldest_queued_s[kind] = 0.0
        for status in _COUNTED:
            out.jobs[(kind, status)] = 0
    rows = session.execute(select(Job.kind, Job.status, func.count(), func.min(Job.created_at))
                           .where(Job.status.in_(_COUNTED)).group_by(Job.kind, Job.status))
    for job_kind, status, count, oldest in rows:
        out.jobs[(job_kind, str(status))] = int(count)
        if status == JobStatus.QUEUED:
            out.queue_depth[job_kind] = int(count)
            out.oldest_queued_s[job_kind] = max(0.0, (now - _aware(oldest)).total_seconds())
    out.timings = _histograms(session.execute(select(
        JobTiming.kind, JobTiming.stage, JobTiming.le, JobTiming.observations,
        JobTiming.seconds)))
    out.attempts = {(k, o): int(n) for k, o, n in session.execute(
        select(JobAttempts.kind, JobAttempts.outcome, JobAttempts.attempts))}
    out.workers = [WorkerBeat(r.worker_id, r.host, r.pid, r.started_at, r.beat_at, r.job_id)
                   for r in session.scalars(select(WorkerHeartbeat)
                                            .order_by(WorkerHeartbeat.worker_id))]
    return out


def _aware(value: datetime) -> datetime:
    # min() keeps the column's type (UTCDateTime, aware); a naive one is UTC all the same
    return value if value.tzinfo else value.replace(tzinfo=timezone.utc)


def _histograms(rows: Iterable[Any]) -> dict[tuple[str, str], Histogram]:
    """Stored (non-cumulative) buckets -> cumulative ones on today's bounds. A stored bound
    that is no longer one of ours counts under the first bound at or above it: never below
    what was observed."""
    grouped: dict[tuple[str, str], list[tuple[float, int, float]]] = {}
    for kind, stage, le, n, seconds in rows:
        grouped.setdefault((kind, stage), []).append((float(le), int(n), float(seconds)))
    out = {}
    for key, stored in grouped.items():
        buckets = [(label, sum(n for bound, n, _ in stored if bound <= float(label)))
                   for label in _LE]
        out[key] = Histogram(buckets, sum(s for _, _, s in stored))
    return out
