"""Read-back of the background job queue for the API (the queue itself: :mod:`server.jobs`)."""

from __future__ import annotations

from sqlalchemy import func, select
from sqlalchemy.orm import Session

from server.errors import NotFound
from server.models import Job

__all__ = ["list_jobs", "get_job"]


def list_jobs(*, session: Session, status: str | None, flight_id: int | None, limit: int,
              offset: int) -> tuple[list[Job], int]:
    """One page of jobs, newest first, and how many match in all."""
    query = select(Job)
    if status:
        query = query.where(Job.status == status)
    if flight_id is not None:
        query = query.where(Job.flight_id == flight_id)
    total = session.scalar(select(func.count()).select_from(query.subquery())) or 0
    rows = session.scalars(query.order_by(Job.id.desc()).limit(limit).offset(offset)).all()
    return list(rows), total


def get_job(*, session: Session, job_id: int) -> Job:
    row = session.get(Job, job_id)
    if row is None:
        raise NotFound(f"Job {job_id} does not exist.")
    return row
