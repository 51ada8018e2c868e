"""Retention of raw flight logs: the bytes of old healthy flights go, their results stay.

A fleet in service uploads a log per flight (about 1.5 MB for a 60 s demo flight), and almost
every one is healthy. With ``HMSM_RAW_RETENTION_HEALTHY=K`` the service keeps, per aircraft,
the raw logs of its K most recent healthy flights -- analysed, and no actuator in alarm on
that flight -- and of every other flight (in alarm, rejected, failed, not yet analysed);
older healthy logs are removed after each analysis. What was computed from them stays: the
flight row with its hash and metadata, features, health records, prognoses. A request for the
signals of a pruned flight answers 410 Gone.

A blob is content-addressed and may back several rows; it is deleted only when no row that
keeps its raw log refers to it.
"""

from __future__ import annotations

import logging

from sqlalchemy import exists, select
from sqlalchemy.orm import Session

from server.blobstore import BlobStore
from server.models import Flight, HealthRecord, utcnow

__all__ = ["healthy_flights_to_prune", "prune_healthy_raw"]

log = logging.getLogger("hmsm.retention")


def healthy_flights_to_prune(*, session: Session, aircraft_id: int, keep: int) -> list[Flight]:
    """The aircraft's analysed flights with no actuator in alarm, still holding their raw log,
    beyond the ``keep`` most recent."""
    in_alarm = exists().where(HealthRecord.flight_id == Flight.id, HealthRecord.alarm.is_(True))
    analysed = exists().where(HealthRecord.flight_id == Flight.id)
    query = (select(Flight).where(Flight.aircraft_id == aircraft_id,
                                  Flight.status == "analyzed", Flight.raw_pruned_at.is_(None),
                                  analysed, ~in_alarm)
             .order_by(Flight.started_at.desc(), Flight.id.desc()).offset(keep))
    return list(session.scalars(query))


def prune_healthy_raw(*, session: Session, blobs: BlobStore, aircraft_id: int, keep: int
                      ) -> int:
    """Remove the raw logs of the aircraft's healthy flights beyond the ``keep`` most recent;
    commit; return how many flights lost their raw log."""
    rows = healthy_flights_to_prune(session=session, aircraft_id=aircraft_id, keep=keep)
    if not rows:
        return 0
    now = utcnow()
    for row in rows:
        row.raw_pruned_at = now
    session.flush()
    orphans = [r.blob_path for r in rows if session.scalar(
        select(Flight.id).where(Flight.sha256 == r.sha256, Flight.raw_pruned_at.is_(None))
        .limit(1)) is None]
    session.commit()  # the rows say "pruned" before the bytes go: never a row without bytes
    for rel in dict.fromkeys(orphans):
        try:
            blobs.delete(rel)
        except OSError as exc:  # the row is pruned either way; the file is only disk
            log.warning("could not delete pruned blob %s: %s", rel, exc)
    return len(rows)
