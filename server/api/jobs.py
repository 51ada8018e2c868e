"""Background job status (read-only)."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Query

from server.api.deps import Reader, SessionDep
from server.schemas import IdPath, IdQuery, JobRead, JobStatusFilter, Offset, Page
from server.services import jobs as service

router = APIRouter(prefix="/jobs", tags=["jobs"])


@router.get("", response_model=Page[JobRead], summary="List jobs")
def list_(session: SessionDep, _: Reader,
          status: JobStatusFilter = None,
          flight_id: IdQuery = None,
          limit: Annotated[int, Query(ge=1, le=500)] = 50,
          offset: Offset = 0) -> Page[JobRead]:
    rows, total = service.list_jobs(session=session, status=status, flight_id=flight_id,
                                    limit=limit, offset=offset)
    return Page(items=[JobRead.model_validate(r) for r in rows], total=total, limit=limit,
                offset=offset)


@router.get("/{job_id}", response_model=JobRead, summary="One job")
def get(job_id: IdPath, session: SessionDep, _: Reader) -> JobRead:
    return JobRead.model_validate(service.get_job(session=session, job_id=job_id))
