"""Decoding an upload of any accepted kind, and the Parquet reader behind the canonical one.

Every reader checks what a file states about its size against :class:`DecodeLimits` before it
decodes a column (docs/SECURITY.md, "Hostile uploads").
"""

from __future__ import annotations

import io
import math
import os
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from server.flightlog.csv_reader import read_csv
from server.flightlog.format import (
    METADATA_FIELDS,
    OPTIONAL_CHANNELS,
    REQUIRED_CHANNELS,
    FlightLog,
    FlightLogError,
    FlightMetadata,
    Issue,
    channel_set_issues,
    stored_channels,
)
from server.flightlog.limits import DEFAULT_DECODE_LIMITS, DecodeLimits, check_rows, too_large
from server.flightlog.mat_reader import read_mat
from server.flightlog.metadata import parse_metadata


def read_flightlog(data: bytes, *, kind: str, metadata: Mapping[str, Any] | None = None,
                   limits: DecodeLimits = DEFAULT_DECODE_LIMITS) -> FlightLog:
    """Decode ``data`` of ``kind`` ``parquet`` | ``csv`` | ``mat`` within ``limits``."""
    if kind == "parquet":
        return read_parquet(data, limits)
    if kind == "csv":
        return read_csv(data, metadata or {}, limits)
    if kind == "mat":
        return read_mat(data, metadata or {}, limits)
    raise ValueError(f"unknown kind {kind!r}")


def _parquet_dtype_issues(schema: Any) -> list[Issue]:
    import pyarrow as pa

    wrong = {}
    for f in schema:
        want = pa.float64() if f.name == "t" else pa.float32()
        if f.name in REQUIRED_CHANNELS or f.name in OPTIONAL_CHANNELS:
            if f.type != want:
                wrong[f.name] = {"found": str(f.type), "expected": str(want)}
    if not wrong:
        return []
    return [Issue("wrong_dtype", f"{len(wrong)} column(s) have the wrong type (t is float64, "
                  "signals float32): " + ", ".join(sorted(wrong)[:6]) + ".", {"columns": wrong})]


def read_parquet(data: bytes, limits: DecodeLimits = DEFAULT_DECODE_LIMITS) -> FlightLog:
    """Decode Parquet bytes; raise :class:`FlightLogError` on anything that is not format v1.

    Sizes, metadata and schema come from the footer and are checked before any column is read;
    columns are then read one at a time. A memory failure is raised as MemoryError, never
    reported as a defect of the file.
    """
    import pyarrow as pa

    pf = _open_parquet(data, limits)
    schema = pf.schema_arrow
    metadata = parse_metadata(_footer_metadata(schema.metadata), limits)
    issues = channel_set_issues(schema.names) + _parquet_dtype_issues(schema)
    if issues:
        raise FlightLogError(issues)
    try:
        channels = {name: pf.read(columns=[name]).column(0).to_numpy() for name in schema.names}
    except MemoryError:
        raise
    except (pa.ArrowException, OSError, ValueError) as exc:
        raise _undecodable_column(exc) from None
    return FlightLog(metadata=metadata, channels=channels)


def read_back(log: FlightLog, limits: DecodeLimits = DEFAULT_DECODE_LIMITS) -> FlightLog:
    """What :func:`read_parquet` returns for :func:`write_parquet`'s bytes of ``log``, without
    encoding them: the stored channels (:func:`stored_channels`, the values a file holds to the
    bit) and the metadata through its strings, within the same limits. A simulated flight whose
    log is not kept is checked and analysed on this."""
    channels = stored_channels(log)
    check_rows(channels["t"].shape[0], sum(v.itemsize for v in channels.values()), limits)
    metadata = parse_metadata(log.metadata.to_strings(), limits)
    return FlightLog(metadata=metadata, channels=channels)


def _undecodable_column(exc: Exception) -> FlightLogError:
    return FlightLogError([Issue("unreadable", "A column of the Parquet file cannot be decoded "
                                 "(truncated or corrupt data).", {"error": str(exc)[:300]})])


def read_parquet_decimated(data: bytes, channels: Sequence[str] | None, max_points: int,
                           limits: DecodeLimits = DEFAULT_DECODE_LIMITS
                           ) -> tuple[int, dict[str, np.ndarray]]:
    """``(step, arrays)``: every ``step``-th sample of ``t`` and of ``channels`` (default: every
    signal channel of the file) so that at most ``max_points`` remain. Read batch by batch, so
    memory grows with a batch and the result, not with the flight. Channels the file does not
    hold are an ``unknown_channel`` issue."""
    import pyarrow as pa

    pf = _open_parquet(data, limits)
    present = pf.schema_arrow.names
    names = list(channels) if channels else [c for c in _SIGNAL_ORDER if c in present]
    unknown = [c for c in names if c not in present]
    if unknown:
        raise FlightLogError([Issue("unknown_channel", "Channel(s) not in this flight: "
                                    + ", ".join(unknown[:6]) + ".", {"channels": unknown})])
    step = max(1, math.ceil(_parquet_rows(pf.metadata) / max_points))
    kept: dict[str, list[np.ndarray]] = {name: [] for name in ["t", *names]}
    seen = 0
    try:
        # one thread: arrow's pool would decode (and hold) every column of a row group at once
        for batch in pf.iter_batches(batch_size=_BATCH_ROWS, columns=list(kept),
                                     use_threads=False):
            first = -seen % step
            for name, parts in kept.items():
                values = batch.column(name).to_numpy(zero_copy_only=False)
                parts.append(values[first::step].copy())  # a view would keep the batch alive
            seen += batch.num_rows
    except MemoryError:
        raise
    except (pa.ArrowException, OSError, ValueError) as exc:
        raise _undecodable_column(exc) from None
    return step, {name: np.concatenate(parts) if parts else np.empty(0)
                  for name, parts in kept.items()}


_SIGNAL_ORDER = REQUIRED_CHANNELS[1:] + OPTIONAL_CHANNELS
_BATCH_ROWS = 1 << 16
_PARQUET_MAGIC = b"PAR1"


def _open_parquet(data: bytes, limits: DecodeLimits) -> Any:
    """A ``pyarrow.parquet.ParquetFile`` whose footer is within the limits: footer size, number
    of columns, samples and decoded bytes (rows times the declared width of every column)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    footer = _parquet_footer_bytes(data)
    if footer > limits.max_footer_bytes:
        raise too_large("max_footer_bytes", limits.max_footer_bytes, footer,
                         "Bytes of the Parquet footer (schema and metadata)")
    try:
        pf = pq.ParquetFile(io.BytesIO(data))
        schema = pf.schema_arrow
    except MemoryError:
        raise
    except (pa.ArrowException, OSError, ValueError) as exc:
        raise _unreadable_parquet(str(exc)) from None
    footer_meta = pf.metadata
    if footer_meta.num_columns > limits.max_columns:
        raise too_large("max_columns", limits.max_columns, footer_meta.num_columns, "Columns")
    check_rows(_parquet_rows(footer_meta), sum(_bytes_per_value(f.type) for f in schema),
                limits)
    return pf


def _parquet_rows(footer_meta: Any) -> int:
    """Rows of the file: its own count and its row groups' are stated apart (a footer may lie
    in one) and the reader goes by the groups, so the larger."""
    groups = sum(footer_meta.row_group(i).num_rows for i in range(footer_meta.num_row_groups))
    return max(footer_meta.num_rows, groups)


def _parquet_footer_bytes(data: bytes) -> int:
    """The footer length stated by the file's last 8 bytes (length, then the magic)."""
    if len(data) < 12 or data[:4] != _PARQUET_MAGIC or data[-4:] != _PARQUET_MAGIC:
        raise _unreadable_parquet("no Parquet magic bytes at both ends")
    return int.from_bytes(data[-8:-4], "little")


def _unreadable_parquet(error: str) -> FlightLogError:
    return FlightLogError([Issue("unreadable", "The file is not readable Parquet (truncated or "
                                 "corrupt).", {"error": error[:300]})])


def _bytes_per_value(dtype: Any) -> int:
    try:
        return max(1, dtype.bit_width // 8)
    except ValueError:  # variable width (strings, lists): costed as a float64
        return 8


def _footer_metadata(raw: Mapping[bytes, bytes] | None) -> dict[str, str]:
    """The format's fields of the key-value metadata (others, like the stored Arrow schema,
    are not decoded)."""
    wanted = {k.encode(): k for k in METADATA_FIELDS}
    return {wanted[k]: v.decode(errors="replace") for k, v in (raw or {}).items() if k in wanted}


def read_parquet_metadata(path: str | os.PathLike[str],
                          limits: DecodeLimits = DEFAULT_DECODE_LIMITS) -> FlightMetadata | None:
    """The metadata of a flight-log Parquet file, read from its footer only and validated as
    an upload's are (:func:`parse_metadata`); None for a file without metadata."""
    import pyarrow.parquet as pq

    raw = pq.read_schema(path).metadata or {}
    if not raw:
        return None
    return parse_metadata(_footer_metadata(raw), limits)
