"""Retention of raw flight logs: the bytes of old flights go, their results stay.

A fleet in service uploads a log per flight (about 1.8 MB for a 60 s demo flight). With
``HMSM_RAW_RETENTION_FLIGHTS=K`` the service keeps, per aircraft, the raw logs of its K most
recent analysed flights, healthy or in alarm, and of the flights that raised an alarm or made
one of its last ``CLASS_CHANGES_KEPT`` class changes (``alarms.flight_id``,
``alarm_events.flight_id``: what an engineer would open to see why); flights not analysed
(queued, rejected, failed) keep theirs. The other analysed flights' logs are removed after
each analysis, so an aircraft holds at most K logs plus 1 + ``CLASS_CHANGES_KEPT`` per alarm,
in alarm or not: an alarm whose class flickers between two modes for hours keeps its latest
changes, not one log per change (the demo's logs grew by 2.4 MB a minute that way). What was
computed from them stays: the flight row with its hash and metadata, features, health
records, prognoses. A request for the signals of a pruned flight answers 410 Gone.

A blob is content-addressed and may back several rows; it is deleted only when no row that
keeps its raw log refers to it. The rows say "pruned" before the bytes go, so a delete that
fails (the object store away, say) leaves an orphan, not a row without bytes; so does a crash
between an upload's blob and its row. :func:`sweep_orphans` (each worker at its start) removes
what no such row refers to, in the local directory and the object store alike.
"""

from __future__ import annotations

import logging
import time

from sqlalchemy import exists, func, select
from sqlalchemy.orm import Session

from server.blobstore import TMP_MAX_AGE_S, BlobStore, relative_path
from server.models import Alarm, AlarmEvent, Flight, utcnow
from server.vocabulary import FlightStatus

__all__ = ["CLASS_CHANGES_KEPT", "flights_to_prune", "prune_raw", "sweep_orphans"]

#: the class changes of one alarm whose flights keep their raw log: the latest ones
CLASS_CHANGES_KEPT = 4

log = logging.getLogger("hmsm.retention")


def flights_to_prune(*, session: Session, aircraft_id: int, keep: int) -> list[Flight]:
    """The aircraft's analysed flights still holding their raw log, beyond its ``keep`` most
    recent analysed ones, that neither raised an alarm nor made one of an alarm's last
    ``CLASS_CHANGES_KEPT`` class changes."""
    analysed = (Flight.aircraft_id == aircraft_id, Flight.status == FlightStatus.ANALYZED)
    recent = list(session.scalars(select(Flight.id).where(*analysed)
                                  .order_by(Flight.started_at.desc(), Flight.id.desc())
                                  .limit(keep)))
    raised = exists().where(Alarm.flight_id == Flight.id)
    rank = func.row_number().over(partition_by=AlarmEvent.alarm_id,
                                  order_by=AlarmEvent.id.desc())
    latest = select(AlarmEvent.flight_id, rank.label("rank")).subquery()
    changed = exists().where(latest.c.flight_id == Flight.id,
                             latest.c.rank <= CLASS_CHANGES_KEPT)
    return list(session.scalars(select(Flight).where(
        *analysed, Flight.raw_pruned_at.is_(None), Flight.id.not_in(recent), ~raised, ~changed)))


def prune_raw(*, session: Session, blobs: BlobStore, aircraft_id: int, keep: int) -> int:
    """Remove the raw logs of :func:`flights_to_prune`; commit; return how many flights lost
    their raw log."""
    rows = flights_to_prune(session=session, aircraft_id=aircraft_id, keep=keep)
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


def _kept_by_a_row(session: Session, sha256: str) -> bool:
    return session.scalar(select(Flight.id).where(
        Flight.sha256 == sha256, Flight.raw_pruned_at.is_(None)).limit(1)) is not None


def sweep_orphans(*, session: Session, blobs: BlobStore,
                  min_age_s: float = TMP_MAX_AGE_S) -> int:
    """Delete the blobs no row keeping its raw log refers to, unwritten for ``min_age_s``
    (a younger one may be an upload whose row is being committed; a commit of bytes already
    stored renews the date); return how many. Each is checked against the rows again just
    before it goes. Objects whose name is no SHA-256 are not ours to remove: left."""
    cutoff = time.time() - min_age_s
    kept = set(session.scalars(select(Flight.sha256).distinct().where(
        Flight.raw_pruned_at.is_(None))))
    removed = 0
    for blob in blobs.stored():
        if blob.name in kept or blob.modified >= cutoff:
            continue
        try:
            rel = relative_path(blob.name)
        except ValueError:
            continue
        if not _kept_by_a_row(session, blob.name):
            blobs.delete(rel)
            removed += 1
    return removed
