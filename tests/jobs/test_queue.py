"""The durable queue: ordering per lock key, leases, retries, dead letters, concurrent claims."""

from __future__ import annotations

import threading
from datetime import timedelta

from sqlalchemy import select, update

from server.jobs import queue
from server.models import Job, utcnow


def add_jobs(factory, keys: list[str], max_attempts: int = 3) -> list[int]:  # type: ignore[no-untyped-def]
    with factory() as s:
        rows = [Job(kind="noop", lock_key=k, max_attempts=max_attempts) for k in keys]
        s.add_all(rows)
        s.commit()
        return [r.id for r in rows]


def test_claims_in_order_one_at_a_time_per_key(factory) -> None:  # type: ignore[no-untyped-def]
    a1, a2, b1 = add_jobs(factory, ["A", "A", "B"])
    first = queue.claim_next(factory, worker_id="w1", lease_s=60)
    second = queue.claim_next(factory, worker_id="w2", lease_s=60)
    assert (first.id, second.id) == (a1, b1)
    assert queue.claim_next(factory, worker_id="w3", lease_s=60) is None  # a2 waits for a1
    with factory() as s:
        assert queue.complete(s, job_id=a1, worker_id="w1")
        s.commit()
    third = queue.claim_next(factory, worker_id="w3", lease_s=60)
    assert third.id == a2 and third.attempts == 1


def test_expired_lease_is_claimed_again_and_old_owner_loses_it(factory) -> None:  # type: ignore[no-untyped-def]
    (job_id,) = add_jobs(factory, ["A"])
    first = queue.claim_next(factory, worker_id="dead-worker", lease_s=60)
    assert queue.claim_next(factory, worker_id="w2", lease_s=60) is None
    with factory() as s:  # time passes beyond the lease: the worker never came back
        s.execute(update(Job).where(Job.id == job_id)
                  .values(lease_until=utcnow() - timedelta(seconds=1)))
        s.commit()
    again = queue.claim_next(factory, worker_id="w2", lease_s=60)
    assert again.id == first.id and again.attempts == 2
    with factory() as s:
        assert not queue.complete(s, job_id=job_id, worker_id="dead-worker")
        assert queue.complete(s, job_id=job_id, worker_id="w2")
        s.commit()
        assert s.get(Job, job_id).status == "done"


def test_retries_with_backoff_then_dead_letter(factory) -> None:  # type: ignore[no-untyped-def]
    failing, after = add_jobs(factory, ["A", "A"], max_attempts=2)
    job = queue.claim_next(factory, worker_id="w", lease_s=60)
    with factory() as s:
        assert queue.fail(s, job=job, worker_id="w", error="boom 1") == "queued"
        s.commit()
        row = s.get(Job, failing)
        assert row.run_after > utcnow() and row.last_error == "boom 1"
    assert queue.claim_next(factory, worker_id="w", lease_s=60) is None  # backing off
    with factory() as s:
        s.execute(update(Job).where(Job.id == failing).values(run_after=utcnow()))
        s.commit()
    job = queue.claim_next(factory, worker_id="w", lease_s=60)
    assert job.id == failing and job.attempts == 2
    with factory() as s:
        assert queue.fail(s, job=job, worker_id="w", error="boom 2") == "dead"
        s.commit()
        row = s.get(Job, failing)
        assert row.status == "dead" and row.last_error == "boom 2" and row.finished_at
    nxt = queue.claim_next(factory, worker_id="w", lease_s=60)  # a dead job does not block
    assert nxt.id == after


def test_job_abandoned_on_its_last_attempt_is_buried_not_claimed_again(factory) -> None:  # type: ignore[no-untyped-def]
    abandoned, after = add_jobs(factory, ["A", "A"], max_attempts=1)
    job = queue.claim_next(factory, worker_id="killed-worker", lease_s=60)
    with factory() as s:
        assert queue.bury_abandoned(s) == []  # its lease still runs
        s.execute(update(Job).where(Job.id == abandoned)
                  .values(lease_until=utcnow() - timedelta(seconds=1)))
        s.commit()
    nxt = queue.claim_next(factory, worker_id="w2", lease_s=60)  # never a second first try
    assert nxt is None
    with factory() as s:
        assert [b.id for b in queue.bury_abandoned(s)] == [job.id]
        assert queue.bury_abandoned(s) == []  # given to one caller only
        s.commit()
        row = s.get(Job, abandoned)
        assert row.status == "dead" and row.last_error == queue.ABANDONED and row.finished_at
        assert not queue.complete(s, job_id=abandoned, worker_id="killed-worker")
        assert queue.fail(s, job=job, worker_id="killed-worker", error="late") == "lost"
    nxt = queue.claim_next(factory, worker_id="w2", lease_s=60)  # a dead job does not block
    assert nxt.id == after


def test_backoff_policy_grows_and_caps() -> None:
    policy = queue.RetryPolicy(base_s=2, max_s=10)
    assert [policy.delay(a).total_seconds() for a in (1, 2, 3, 4, 5)] == [2, 4, 8, 10, 10]


def test_concurrent_workers_never_share_a_job_or_a_key(factory) -> None:  # type: ignore[no-untyped-def]
    keys = [f"K{i % 5}" for i in range(60)]
    add_jobs(factory, keys)
    running: dict[str, str] = {}
    claimed: list[int] = []
    violations: list[str] = []
    order: dict[str, list[int]] = {}
    guard = threading.Lock()

    def work(name: str) -> None:
        while True:
            job = queue.claim_next(factory, worker_id=name, lease_s=60)
            if job is None:
                with factory() as s:
                    left = s.scalar(select(Job.id).where(Job.status != "done").limit(1))
                if left is None:
                    return
                continue
            with guard:
                if job.lock_key in running:
                    violations.append(f"{job.lock_key} by {running[job.lock_key]} and {name}")
                running[job.lock_key] = name
                claimed.append(job.id)
                order.setdefault(job.lock_key, []).append(job.id)
            # released just before the completion commits: from the commit on, another worker
            # may rightly claim the key's next job (releasing after it made this check racy)
            with guard:
                del running[job.lock_key]
            with factory() as s:
                queue.complete(s, job_id=job.id, worker_id=name)
                s.commit()

    threads = [threading.Thread(target=work, args=(f"w{i}",)) for i in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=120)
    assert not violations
    assert sorted(claimed) == sorted(set(claimed)) and len(claimed) == 60
    assert all(ids == sorted(ids) for ids in order.values())  # flight order kept per key
