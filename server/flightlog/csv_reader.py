"""CSV uploads (plain or gzip), streamed so that no text is ever held whole."""

from __future__ import annotations

import gzip
import io
import itertools
import warnings
import zlib
from collections.abc import Mapping
from typing import Any

import numpy as np

from server.flightlog.format import FlightLog, FlightLogError, Issue, channel_set_issues
from server.flightlog.limits import DEFAULT_DECODE_LIMITS, DecodeLimits, check_rows, too_large
from server.flightlog.metadata import parse_metadata

#: the CSV bytes as a stream: plain, or decompressed on the fly
_Stream = gzip.GzipFile | io.BytesIO


def read_csv(data: bytes, metadata: Mapping[str, Any],
             limits: DecodeLimits = DEFAULT_DECODE_LIMITS) -> FlightLog:
    """Decode CSV (gzip detected by its magic bytes) with a header row of channel names.

    The text is streamed, never held whole: one pass counts and measures its lines (refusing
    past the decompressed-bytes, line-length or row limits before a number is parsed), a second
    parses it block by block into arrays of the canonical types.
    """
    meta = parse_metadata(metadata, limits)
    try:
        names = _csv_header(_csv_bytes(data), limits)
        issues = channel_set_issues(names)
        if issues:
            raise FlightLogError(issues)
        lines, returns = _scan_csv(_csv_bytes(data), limits)
        row_bytes = sum(8 if n == "t" else 4 for n in names)
        check_rows(max(lines, returns) - 1, row_bytes, limits)  # below the header
        # universal newlines: a text never has more lines than LF + CR + 1
        capacity = min(limits.max_rows(row_bytes), lines + returns)
        columns = _parse_csv(_csv_bytes(data), names, capacity, limits)
    except (OSError, EOFError, zlib.error, UnicodeDecodeError) as exc:
        raise FlightLogError([Issue("unreadable", "The CSV file is not readable text (bad gzip "
                                    "or encoding).", {"error": str(exc)[:300]})]) from None
    return FlightLog(meta, columns)


_GZIP_MAGIC = b"\x1f\x8b"
_CHUNK_BYTES = 1 << 20
_CSV_BLOCK_ROWS = 4096
_LF, _CR = 0x0A, 0x0D


def _csv_bytes(data: bytes) -> _Stream:
    """The CSV text as a binary stream, decompressed on the fly when gzip."""
    raw = io.BytesIO(data)
    return gzip.GzipFile(fileobj=raw, mode="rb") if data[:2] == _GZIP_MAGIC else raw


def _csv_header(stream: _Stream, limits: DecodeLimits) -> list[str]:
    line = stream.readline(limits.max_line_chars + 1)
    if len(line) > limits.max_line_chars:
        raise too_large("max_line_chars", limits.max_line_chars, None,
                         "Characters of the CSV header line")
    names = [h.strip() for h in line.decode("utf-8").strip().split(",")]
    if len(names) > limits.max_columns:
        raise too_large("max_columns", limits.max_columns, len(names), "Columns")
    return names


def _scan_csv(stream: _Stream, limits: DecodeLimits) -> tuple[int, int]:
    """``(lines, carriage returns)`` of the text (lines ended by a line feed or the end), read
    one chunk at a time; every line checked against ``max_line_chars`` and the whole against
    ``max_decompressed_bytes``."""
    total = line_feeds = returns = run = 0
    while chunk := stream.read(_CHUNK_BYTES):
        total += len(chunk)
        if total > limits.max_decompressed_bytes:
            raise too_large("max_decompressed_bytes", limits.max_decompressed_bytes, None,
                             "Bytes of CSV text (decompressed)")
        octets = np.frombuffer(chunk, dtype=np.uint8)
        ends = np.flatnonzero(octets == _LF)
        run = _line_run(ends, len(chunk), run, limits)
        line_feeds += int(ends.size)
        returns += int(np.count_nonzero(octets == _CR))
    return line_feeds + (run > 0), returns


def _line_run(ends: np.ndarray, size: int, run: int, limits: DecodeLimits) -> int:
    """Length of the unfinished last line after a chunk of ``size`` bytes with line feeds at
    ``ends``, the previous chunk having left one of ``run``; refuse any line too long."""
    if ends.size:
        longest = max(run + int(ends[0]), int(np.diff(ends).max(initial=1)) - 1)
        run = size - int(ends[-1]) - 1
    else:
        longest = run = run + size
    if max(longest, run) > limits.max_line_chars:
        raise too_large("max_line_chars", limits.max_line_chars, None,
                         "Characters of a CSV line")
    return run


def _parse_csv(stream: _Stream, names: list[str], capacity: int,
               limits: DecodeLimits) -> dict[str, np.ndarray]:
    """The rows below the header parsed block by block into preallocated canonical arrays
    (t float64, signals float32): peak memory is the result plus one block."""
    text = io.TextIOWrapper(stream, encoding="utf-8")
    text.readline()  # the header, checked before
    columns = {n: np.empty(capacity, dtype=np.float64 if n == "t" else np.float32)
               for n in names}
    filled = 0
    while block := list(itertools.islice(text, _CSV_BLOCK_ROWS)):
        values = _csv_block(block, len(names))
        if filled + len(values) > capacity:  # only past max_rows: see the capacity
            check_rows(filled + len(values), sum(c.itemsize for c in columns.values()),
                        limits)
            raise AssertionError("more CSV lines than line ends")
        for i, column in enumerate(columns.values()):
            column[filled:filled + len(values)] = values[:, i]
        filled += len(values)
    if filled == 0:
        raise FlightLogError([Issue("unreadable", "The CSV file has no data rows.", {})])
    for column in columns.values():
        column.resize(filled, refcheck=False)  # in place: no second copy of the flight
    return columns


def _csv_block(lines: list[str], n_columns: int) -> np.ndarray:
    bad_rows = Issue("unreadable", "The CSV body has rows that are not numbers or have the "
                     "wrong number of fields.", {})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # a block of blank lines holds no data
        try:
            values = np.loadtxt(lines, delimiter=",", dtype=np.float64, ndmin=2)
        except ValueError as exc:
            raise FlightLogError([Issue(bad_rows.code, bad_rows.message,
                                        {"error": str(exc)[:300]})]) from None
    if values.shape[0] and values.shape[1] != n_columns:
        raise FlightLogError([bad_rows])
    return values.reshape(-1, n_columns) if values.shape[0] else np.empty((0, n_columns))
