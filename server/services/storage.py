"""What the service keeps, and the bound on what one key may make it keep.

**The rejected-bytes quota.** A rejected flight log is kept (bytes and row) for forensics, and
nothing else bounds it: one key sending junk could fill the disk (an outside probe stored
200 MB in 1.8 s with 10 files of 20 MiB). So each key's rejected flights are charged against
``HMSM_REJECTED_BYTES_PER_KEY``: every rejected row its file's size, at least
:data:`REJECTED_MIN_CHARGE` (a row holds up to 40 KB of reasons in the database, and the
floor bounds the number of rows as well as the bytes). A file that would go past the quota is
not kept (:func:`check_rejected_quota`, 507). Rows are charged, not distinct files: the same
bytes sent with other form metadata make another row.

**The report** (``GET /api/v1/storage``, admin): flight logs by state and reason (rows, and the
bytes of their distinct files), each key's rejected share against its quota, the blob store
as it is on disk (files referenced by a row that keeps its log, files no row refers to, rows
whose file is missing), and every file under the data directory by kind (blobs, temporary
uploads, campaigns, evaluation reports, the SQLite database, logs, anything else), whose bytes
add up to the directory's.
"""

from __future__ import annotations

import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from sqlalchemy import case, func, select, text
from sqlalchemy.orm import Session

from server.blobstore import BlobStore, files_under
from server.config import SQLITE_FILE_NAME
from server.errors import DomainError
from server.models import ApiKey, Flight
from server.vocabulary import FlightStatus

__all__ = ["REJECTED_MIN_CHARGE", "RejectedQuotaExceeded", "rejected_charge",
           "check_rejected_quota", "storage_report"]

#: the least a rejected flight is charged against its key's quota [B]
REJECTED_MIN_CHARGE = 64 * 1024
#: what the top-level entries of the data directory hold (``server.config.Settings``, the
#: campaigns and the evaluation of :mod:`server.services.models` and ``server.demo``)
_TOP_LEVEL = {"blobs": "blobs", "tmp": "temporary_uploads", "campaigns": "campaign",
              "evaluation": "evaluation_reports", "logs": "logs"}
_SQLITE_FILES = tuple(SQLITE_FILE_NAME + end for end in ("", "-wal", "-shm", "-journal"))


class RejectedQuotaExceeded(DomainError):
    """A rejected file would take its key past ``HMSM_REJECTED_BYTES_PER_KEY``; not kept."""

    status_code, code = 507, "rejected_quota_exceeded"


def _charge(size: Any) -> Any:
    return case((size < REJECTED_MIN_CHARGE, REJECTED_MIN_CHARGE), else_=size)


def rejected_charge(session: Session, *, key_id: int) -> int:
    """What the key's rejected flights take of its quota [B]."""
    return int(session.scalar(select(func.coalesce(func.sum(_charge(Flight.size_bytes)), 0))
                              .where(Flight.uploader_key_id == key_id,
                                     Flight.status == FlightStatus.REJECTED)) or 0)


def check_rejected_quota(session: Session, *, key_id: int, size: int, quota: int,
                         reasons: list[dict[str, Any]]) -> None:
    """Raise :class:`RejectedQuotaExceeded`, with the file's reasons (the client still learns
    what is wrong with it), when keeping one more rejected file of ``size`` bytes would take
    the key past ``quota``. The key's row is locked first (PostgreSQL), so that two uploads of
    one key are charged one after the other, not both against the same sum."""
    session.execute(select(ApiKey.id).where(ApiKey.id == key_id).with_for_update())
    stored = rejected_charge(session, key_id=key_id)
    charge = max(size, REJECTED_MIN_CHARGE)
    if stored + charge <= quota:
        return
    raise RejectedQuotaExceeded(
        f"The flight log failed the coherence checks (reasons below) and was not kept: the "
        f"rejected flight logs of this key already take {stored} of its {quota} bytes "
        f"(HMSM_REJECTED_BYTES_PER_KEY) and this one would take {charge} more. Nothing was "
        "registered. Correct the files before sending more; an admin can see what is kept "
        "(GET /api/v1/storage) and delete rejected flights (DELETE /api/v1/flights/{id}).",
        details={"quota_bytes": quota, "stored_bytes": stored, "file_bytes": size,
                 "charged_bytes": charge, "reasons": reasons})


# ------------------------------------------------------------------------------ the report

@dataclass
class _Tally:
    files: int = 0
    bytes: int = 0

    def add(self, size: int) -> None:
        self.files += 1
        self.bytes += size

    def as_dict(self) -> dict[str, int]:
        return {"files": self.files, "bytes": self.bytes}


def _file_kinds(data_dir: Path) -> tuple[list[dict[str, Any]], _Tally]:
    """The data directory's files by kind (campaigns one by one), and all of them."""
    tallies: dict[tuple[str, str | None], _Tally] = {}
    total = _Tally()
    for path, stat in files_under(data_dir):
        size = stat.st_size
        parts = path.relative_to(data_dir).parts
        if len(parts) == 1 and parts[0] in _SQLITE_FILES:
            key: tuple[str, str | None] = ("database", None)
        elif parts[0] in _TOP_LEVEL and len(parts) > 1:
            kind = _TOP_LEVEL[parts[0]]
            key = (kind, parts[1] if kind == "campaign" and len(parts) > 2 else None)
        else:
            key = ("other", None)
        tallies.setdefault(key, _Tally()).add(size)
        total.add(size)
    items = [{"kind": kind, "name": name, **t.as_dict()}
             for (kind, name), t in sorted(tallies.items(), key=lambda kv: (kv[0][0],
                                                                             kv[0][1] or ""))]
    return items, total


def _flight_logs(session: Session) -> list[dict[str, Any]]:
    """Flight rows by state and reason: accepted ones by status, rejected ones by their first
    reason's code, and the analysed ones whose log the retention removed."""
    rejected = Flight.status == FlightStatus.REJECTED
    kept = Flight.raw_pruned_at.is_(None)
    reason = Flight.reasons[0]["code"].as_string()
    groups = [("accepted", Flight.status, ~rejected & kept),
              ("rejected", reason, rejected & kept),
              ("raw_pruned", Flight.status, Flight.raw_pruned_at.is_not(None))]
    items = []
    for state, label, where in groups:
        rows = select(label.label("reason"), Flight.sha256, Flight.size_bytes, Flight.id).where(
            where).subquery()
        blobs = select(rows.c.reason, rows.c.sha256, rows.c.size_bytes).distinct().subquery()
        sizes = dict(session.execute(select(blobs.c.reason, func.sum(blobs.c.size_bytes))
                                     .group_by(blobs.c.reason)).all())
        for name, count in session.execute(select(rows.c.reason, func.count(rows.c.id))
                                           .group_by(rows.c.reason)).all():
            items.append({"state": state, "reason": str(name) if name is not None else None,
                          "flights": int(count),
                          "bytes": 0 if state == "raw_pruned" else int(sizes.get(name) or 0)})
    return sorted(items, key=lambda i: (i["state"], i["reason"] or ""))


def _rejected_by_key(session: Session, quota: int) -> list[dict[str, Any]]:
    rows = session.execute(
        select(Flight.uploader_key_id, ApiKey.name, ApiKey.role, func.count(Flight.id),
               func.sum(Flight.size_bytes), func.sum(_charge(Flight.size_bytes)))
        .join(ApiKey, ApiKey.id == Flight.uploader_key_id, isouter=True)
        .where(Flight.status == FlightStatus.REJECTED)
        .group_by(Flight.uploader_key_id, ApiKey.name, ApiKey.role)
        .order_by(Flight.uploader_key_id))
    return [{"key_id": key_id, "key_name": name, "role": role, "flights": int(count),
             "bytes": int(size or 0), "charged_bytes": int(charged or 0), "quota_bytes": quota}
            for key_id, name, role, count, size, charged in rows]


def _blob_store(session: Session, blobs: BlobStore) -> dict[str, int]:
    """The blob store as it is (directory or object store): files a row keeping its log
    refers to, files none does (a crash between the bytes and the row, say), and rows whose
    file is not there."""
    wanted = set(session.scalars(select(Flight.sha256).distinct().where(
        Flight.raw_pruned_at.is_(None))))
    referenced, unreferenced = _Tally(), _Tally()
    for name, size, _ in blobs.stored():
        (referenced if name in wanted else unreferenced).add(size)
        wanted.discard(name)
    return {"files": referenced.files + unreferenced.files,
            "bytes": referenced.bytes + unreferenced.bytes,
            "referenced_files": referenced.files, "referenced_bytes": referenced.bytes,
            "unreferenced_files": unreferenced.files, "unreferenced_bytes": unreferenced.bytes,
            "missing_files": len(wanted)}


def _database(session: Session) -> dict[str, Any]:
    dialect = session.get_bind().dialect.name
    if dialect == "postgresql":
        size = session.scalar(text("SELECT pg_database_size(current_database())"))
        return {"dialect": dialect, "bytes": int(size or 0)}
    return {"dialect": dialect, "bytes": None}  # a file under the data directory: see files


def storage_report(session: Session, *, data_dir: Path, blobs: BlobStore,
                   rejected_quota: int) -> dict[str, Any]:
    """Everything the service keeps, counted now (the module docstring)."""
    files, total = _file_kinds(data_dir)
    existing = next(p for p in (data_dir, *data_dir.parents) if p.exists())
    return {
        "flight_logs": _flight_logs(session),
        "rejected_by_key": _rejected_by_key(session, rejected_quota),
        "blob_store": _blob_store(session, blobs),
        "files": files,
        "data_dir": {**total.as_dict(), "free_bytes": shutil.disk_usage(existing).free},
        "database": _database(session),
    }
