"""The analysis job's input: a stored flight's bytes, verified and decoded once.

The API decoded the upload to check it (:func:`server.services.flights.ingest_flight`) and
kept only its bytes; the job runs in a worker process, maybe on another host, so it reads
them back from the blob store and decodes them again, once: the job computes the features on
that log (:func:`server.phm.recording.log_features`) and hands only the features on.
"""

from __future__ import annotations

import hashlib
from typing import Any

from server.blobstore import BlobStore
from server.flightlog import (
    DecodeLimits,
    FlightLog,
    FlightLogError,
    bounded_reasons,
    read_flightlog,
)
from server.services.analysis import FlightToAnalyse

__all__ = ["Unanalysable", "decode_stored"]


class Unanalysable(Exception):
    """The stored flight cannot be analysed (damaged on disk, or not decodable); ``reasons``,
    machine-readable and bounded, say why."""

    def __init__(self, reasons: list[dict[str, Any]]):
        self.reasons = reasons
        super().__init__("; ".join(str(r.get("message", "")) for r in reasons))


def decode_stored(*, blobs: BlobStore, todo: FlightToAnalyse, limits: DecodeLimits) -> FlightLog:
    """The flight's stored bytes checked against their SHA-256 and decoded within ``limits``.

    Raises :class:`Unanalysable` when the bytes changed on disk after ingest or do not decode
    (nothing to retry), and the reader's :class:`~server.flightlog.FlightLogError` when they
    are past this worker's limits (not a defect of the file: the job fails and is retried).
    """
    data = blobs.read(todo.blob_path)
    if hashlib.sha256(data).hexdigest() != todo.sha256:
        raise Unanalysable([{
            "code": "blob_corrupt", "message": "The stored file no longer matches its SHA-256; "
            "it was corrupted on disk after upload.", "details": {"sha256": todo.sha256}}])
    try:
        return read_flightlog(data, kind=todo.content_kind, metadata=todo.metadata,
                              limits=limits)
    except FlightLogError as exc:
        if exc.too_large:
            raise
        raise Unanalysable(bounded_reasons((i.as_dict() for i in exc.issues), limits)) from None
