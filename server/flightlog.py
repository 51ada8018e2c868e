"""Flight-log format v1 (``ema-flightlog/1``): the contract between data sources and the HMSM.

One file per flight download (docs/ARCHITECTURE.md, Contracts). Canonical encoding is Apache
Parquet with zstd compression; CSV (plain or gzip) and MATLAB v5 ``.mat`` are accepted on
upload with the metadata given separately (form fields).

Conventions
-----------
* Column ``t``: seconds from the start of the recording, float64, strictly increasing, 800 Hz.
* Per actuator position ``A`` in ``WL1``, ``WL2``, ``WT``: ``A.ia A.ib A.ic`` phase currents [A],
  ``A.va A.vb A.vc`` phase voltages [V], ``A.theta`` resolver motor-shaft angle [rad, unwrapped],
  ``A.x`` LVDT rod position [m]; float32, SI units.
* Optional: ``A.x_cmd`` [m], ``T_amb`` [degC], ``surf_WL`` and ``surf_WT`` surface deflection [rad].

Every coherence problem is reported as an :class:`Issue` with a machine-readable ``code`` and a
human sentence; a file may have several. This module imports nothing else of ours so the simulator
can use it (``sim_worker`` writes, ``server`` reads and checks).
"""

from __future__ import annotations

import gzip
import io
import itertools
import json
import math
import os
import re
import struct
import warnings
import zlib
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from datetime import datetime, timezone
from typing import Any, NamedTuple

import numpy as np

from server.vocabulary import POSITIONS, SIGNALS, WINGLET_PAIR

__all__ = [
    "FORMAT",
    "POSITIONS",
    "SIGNALS",
    "REQUIRED_CHANNELS",
    "OPTIONAL_CHANNELS",
    "METADATA_FIELDS",
    "ID_PATTERN",
    "MAX_ID_LEN",
    "MAX_BLOCK_HOURS",
    "valid_id",
    "NOMINAL_SAMPLE_RATE_HZ",
    "PhysicalLimits",
    "DecodeLimits",
    "DEFAULT_DECODE_LIMITS",
    "Issue",
    "FlightLogError",
    "FlightMetadata",
    "FlightLog",
    "stored_channels",
    "write_parquet",
    "read_parquet",
    "read_back",
    "read_parquet_metadata",
    "read_parquet_decimated",
    "read_csv",
    "read_mat",
    "read_flightlog",
    "parse_metadata",
    "check_coherence",
    "bounded_reasons",
]

FORMAT = "ema-flightlog/1"
NOMINAL_SAMPLE_RATE_HZ = 800.0
REQUIRED_CHANNELS: tuple[str, ...] = ("t",) + tuple(f"{p}.{s}" for p in POSITIONS for s in SIGNALS)
OPTIONAL_CHANNELS: tuple[str, ...] = tuple(f"{p}.x_cmd" for p in POSITIONS) + (
    "T_amb",
    "surf_WL",
    "surf_WT",
)
_REQUIRED_METADATA = (
    "format",
    "aircraft",
    "flight",
    "started_at",
    "block_hours",
    "sample_rate_hz",
    "actuator_serials",
)
#: ``active_channels``: the positions whose drives were active on the flight, a JSON list (an
#: active-standby winglet names one of its pair); absent when every drive was active, so that
#: logs without it read as they always did
_OPTIONAL_METADATA = ("source", "active_channels")
#: every metadata field of the format (Parquet key-value metadata, or upload form fields)
METADATA_FIELDS: tuple[str, ...] = _REQUIRED_METADATA + _OPTIONAL_METADATA
MAX_ID_LEN = 64
#: longest block time of one flight [h]: a day; beyond it a value is a unit or typing error
MAX_BLOCK_HOURS = 24.0
#: tails, flight codes and serials: ASCII letters, digits, '.', '_', '-', not only dots ('..'
#: would name a parent directory wherever an id becomes a path segment)
ID_PATTERN = r"^[A-Za-z0-9._-]*[A-Za-z0-9_-][A-Za-z0-9._-]*$"
_ID_RE = re.compile(ID_PATTERN)


@dataclass(frozen=True)
class PhysicalLimits:
    """Bounds beyond which a recorded value cannot come from a working EMA.

    Values follow the simulated servo motor (docs/SIMULATOR.md): rated 12 A_rms (peak 17 A);
    the check rejects currents beyond 3x rated. The rod stroke is +-30 mm about neutral (the
    simulator's stroke); a 5 mm margin covers LVDT offset and overtravel into the end stops.
    """

    rated_current_a_rms: float = 12.0  # A rms
    current_factor: float = 3.0  # -
    stroke_half_m: float = 0.030  # m
    stroke_margin_m: float = 0.005  # m
    max_missed_samples: int = 2  # samples; a larger gap is rejected
    sample_rate_tolerance: float = 0.01  # relative
    min_duration_s: float = 10.0  # s, shortest recording that holds a feature window

    @property
    def max_current_a(self) -> float:
        """Largest credible instantaneous phase current [A]."""
        return self.current_factor * self.rated_current_a_rms * math.sqrt(2.0)

    @property
    def max_abs_position_m(self) -> float:
        """Largest credible |rod position| [m]."""
        return self.stroke_half_m + self.stroke_margin_m


DEFAULT_LIMITS = PhysicalLimits()

_MIB = 1 << 20


@dataclass(frozen=True)
class DecodeLimits:
    """What a reader may build from untrusted bytes (docs/SECURITY.md, "Hostile uploads").

    Checked before decoding where the file states its size (Parquet footer, MAT variable
    headers, the CSV header line) and while decoding where it does not (gzip text, CSV lines).
    Past a limit a reader raises :class:`FlightLogError` with a ``too_large`` issue naming the
    limit (metadata past its limits is ``bad_metadata``); it never allocates beyond them. The
    service takes every value from its settings (``HMSM_<FIELD NAME>``).
    """

    # gzip CSV text; 4x the 64 MiB upload limit, above the ~2.5:1 gzip reaches on decimal text
    max_decompressed_bytes: int = 256 * _MIB
    # a 12 h recording at 800 Hz; with the defaults max_decoded_bytes binds first (~44 min)
    max_samples_per_channel: int = 12 * 3600 * 800
    # every channel decoded (t float64, signals float32); 4x the upload limit, above the
    # 3.3:1 zstd reaches on the simulator's 800 Hz signals
    max_decoded_bytes: int = 256 * _MIB
    max_columns: int = 64  # format v1 has at most 31 channels
    max_line_chars: int = 4096  # one CSV line: 64 fields of up to 64 characters
    max_footer_bytes: int = 1 * _MIB  # Parquet footer: schema, row groups, key-value metadata
    max_metadata_chars: int = 1024  # per metadata value; the longest valid one is ~230
    max_json_depth: int = 4  # nesting of actuator_serials, a flat object (depth 1)
    max_reason_chars: int = 2048  # one stored or echoed reason, as JSON
    max_reasons: int = 20

    def max_rows(self, row_bytes: int) -> int:
        """Most samples per channel a file may hold whose one sample of every channel takes
        ``row_bytes`` decoded."""
        return min(self.max_samples_per_channel, self.max_decoded_bytes // max(1, row_bytes))


DEFAULT_DECODE_LIMITS = DecodeLimits()


@dataclass(frozen=True)
class Issue:
    """One coherence problem: ``code`` for machines, ``message`` for people."""

    code: str
    message: str
    details: dict[str, Any] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        return {"code": self.code, "message": self.message, "details": self.details}


class FlightLogError(ValueError):
    """Raised when a file cannot be turned into a :class:`FlightLog`; carries the issues."""

    def __init__(self, issues: list[Issue]):
        self.issues = issues
        super().__init__("; ".join(i.message for i in issues))

    @property
    def too_large(self) -> bool:
        """The file was refused for its size (a :class:`DecodeLimits` limit), not its content."""
        return any(i.code == "too_large" for i in self.issues)


def _too_large(limit: str, maximum: int, found: int | None, what: str) -> FlightLogError:
    """``what`` went past ``limit`` (a :class:`DecodeLimits` field); ``found`` None: unknown
    beyond the limit (the reader stopped there)."""
    amount = f"more than {maximum}" if found is None else f"{found}, more than {maximum}"
    return FlightLogError([Issue("too_large", f"{what}: {amount} (limit {limit}).",
                                 {"limit": limit, "maximum": maximum, "found": found})])


_FEW_ITEMS, _SHORT_TEXT = 8, 120


def bounded_reasons(reasons: Iterable[Mapping[str, Any]],
                    limits: DecodeLimits = DEFAULT_DECODE_LIMITS) -> list[dict[str, Any]]:
    """Reasons as they are stored and echoed: at most ``max_reasons``, each at most
    ``max_reason_chars`` as JSON (long messages cut, long details shortened), so that no file
    makes its own rejection large."""
    items = list(reasons)
    if len(items) <= limits.max_reasons:
        return [_bounded_reason(r, limits.max_reason_chars) for r in items]
    kept = [_bounded_reason(r, limits.max_reason_chars) for r in items[:limits.max_reasons - 1]]
    left = len(items) - len(kept)
    return kept + [{"code": "more_reasons", "message": f"{left} more reasons not shown.",
                    "details": {"count": left}}]


def _bounded_reason(reason: Mapping[str, Any], max_chars: int) -> dict[str, Any]:
    code = str(reason.get("code", ""))[:64]
    message = str(reason.get("message", ""))
    if len(message) > max_chars // 2:
        message = message[:max_chars // 2 - 3] + "..."
    details = reason.get("details") or {}
    room = max_chars - len(code) - len(message) - 64  # JSON keys and quotes
    if _json_len(details) > room:
        details = {**_shortened(details), "truncated": True}
        if _json_len(details) > room:
            details = {"truncated": True}
    return {"code": code, "message": message, "details": details}


def _json_len(value: Any) -> int:
    return len(json.dumps(value, default=str))


def _shortened(value: Any, depth: int = 0) -> Any:
    if isinstance(value, str):
        return value[:_SHORT_TEXT]
    if depth >= 3:
        return "..."
    if isinstance(value, Mapping):
        return {str(k)[:_SHORT_TEXT]: _shortened(v, depth + 1)
                for k, v in list(value.items())[:_FEW_ITEMS]}
    if isinstance(value, list | tuple):
        return [_shortened(v, depth + 1) for v in value[:_FEW_ITEMS]]
    return value


@dataclass(frozen=True)
class FlightMetadata:
    """Flight-level metadata (Parquet key-value metadata, or form fields on CSV/MAT upload)."""

    aircraft: str
    flight: str
    started_at: datetime
    block_hours: float
    sample_rate_hz: float
    actuator_serials: dict[str, str]
    source: str | None = None
    active_channels: tuple[str, ...] | None = None
    format: str = FORMAT

    def to_strings(self) -> dict[str, str]:
        out = {
            "format": self.format,
            "aircraft": self.aircraft,
            "flight": self.flight,
            "started_at": self.started_at.astimezone(timezone.utc).isoformat(),
            "block_hours": repr(float(self.block_hours)),
            "sample_rate_hz": repr(float(self.sample_rate_hz)),
            "actuator_serials": json.dumps(self.actuator_serials, sort_keys=True),
        }
        if self.source is not None:
            out["source"] = self.source
        if self.active_channels is not None:
            out["active_channels"] = json.dumps(list(self.active_channels))
        return out


@dataclass
class FlightLog:
    """A decoded flight download: metadata plus named 1-D channel arrays of equal length."""

    metadata: FlightMetadata
    channels: dict[str, np.ndarray]

    @property
    def n_samples(self) -> int:
        return int(self.channels["t"].shape[0]) if "t" in self.channels else 0

    @property
    def duration_s(self) -> float:
        t = self.channels.get("t")
        return float(t[-1] - t[0]) if t is not None and t.size > 1 else 0.0


# --------------------------------------------------------------------------------------------
# metadata
# --------------------------------------------------------------------------------------------


def valid_id(value: str) -> bool:
    return len(value) <= MAX_ID_LEN and _ID_RE.fullmatch(value) is not None


def parse_metadata(raw: Mapping[str, Any],
                   limits: DecodeLimits = DEFAULT_DECODE_LIMITS) -> FlightMetadata:
    """Validate raw string metadata into :class:`FlightMetadata`.

    Raises :class:`FlightLogError` with ``unknown_format``, ``missing_metadata`` or
    ``bad_metadata`` issues. Values longer than ``limits.max_metadata_chars`` are refused before
    any is parsed or quoted in a message.
    """
    _check_metadata_lengths(raw, limits)
    issues: list[Issue] = []
    fmt = raw.get("format")
    if fmt is None:
        issues.append(Issue("unknown_format", "The file does not say which format it is in.",
                            {"expected": FORMAT}))
    elif str(fmt) != FORMAT:
        issues.append(Issue("unknown_format", f"Format '{fmt}' is not supported; expected "
                            f"'{FORMAT}'.", {"found": str(fmt), "expected": FORMAT}))
    missing = [k for k in _REQUIRED_METADATA if k != "format" and raw.get(k) in (None, "")]
    if missing:
        issues.append(Issue("missing_metadata", "Required metadata is missing: "
                            + ", ".join(missing) + ".", {"missing": missing}))
    if issues:
        raise FlightLogError(issues)

    bad: dict[str, str] = {}
    aircraft, flight = str(raw["aircraft"]), str(raw["flight"])
    for key, value in (("aircraft", aircraft), ("flight", flight)):
        if not valid_id(value):
            bad[key] = "1-64 ASCII letters, digits, '-', '_' and '.', not only dots"
    started_at = None
    try:
        started_at = datetime.fromisoformat(str(raw["started_at"]).replace("Z", "+00:00"))
        if started_at.tzinfo is None:
            bad["started_at"] = "ISO 8601 with a UTC offset"
    except ValueError:
        bad["started_at"] = "ISO 8601 with a UTC offset"
    numbers: dict[str, float] = {}
    for key, most in (("block_hours", MAX_BLOCK_HOURS), ("sample_rate_hz", math.inf)):
        try:
            numbers[key] = float(raw[key])
            if not math.isfinite(numbers[key]) or not 0 < numbers[key] <= most:
                raise ValueError
        except (TypeError, ValueError):
            bad[key] = ("a positive finite number" if most == math.inf
                        else f"a positive number, at most {most:g}")
    serials: dict[str, str] = {}
    try:
        parsed = raw["actuator_serials"]
        if isinstance(parsed, str):
            parsed = _shallow_json(parsed, limits.max_json_depth)
        if not isinstance(parsed, dict) or set(parsed) != set(POSITIONS):
            raise ValueError
        serials = {str(k): str(v) for k, v in parsed.items()}
        if not all(valid_id(v) for v in serials.values()):
            raise ValueError
    except (TypeError, ValueError):
        bad["actuator_serials"] = 'a JSON object {"WL1": serial, "WL2": serial, "WT": serial}'
    source = raw.get("source")
    if source is not None and len(str(source)) > 200:
        bad["source"] = "at most 200 characters"
    active = _active_channels(raw.get("active_channels"), limits)
    if active == ():
        bad["active_channels"] = ('a JSON list of distinct positions, each of "WL1", "WL2", '
                                  '"WT", with at least one drive of each surface')
    if bad:
        raise FlightLogError([Issue("bad_metadata", "Metadata values are malformed: "
                                    + ", ".join(f"{k} must be {v}" for k, v in bad.items()) + ".",
                                    {"fields": bad})])
    assert started_at is not None  # for the type checker: None only with bad["started_at"]
    return FlightMetadata(
        aircraft=aircraft,
        flight=flight,
        started_at=started_at.astimezone(timezone.utc),
        block_hours=numbers["block_hours"],
        sample_rate_hz=numbers["sample_rate_hz"],
        actuator_serials=serials,
        source=None if source is None else str(source),
        active_channels=active,
    )


def _active_channels(raw: Any, limits: DecodeLimits) -> tuple[str, ...] | None:
    """The optional ``active_channels`` list: None when absent, ``()`` when malformed."""
    if raw is None or raw == "":
        return None
    try:
        parsed = _shallow_json(str(raw), limits.max_json_depth) if isinstance(raw, str) else raw
    except ValueError:
        return ()
    if (not isinstance(parsed, list) or not all(isinstance(p, str) for p in parsed)
            or len(set(parsed)) != len(parsed) or not set(parsed) <= set(POSITIONS)
            or not set(parsed) & set(WINGLET_PAIR)
            or not set(POSITIONS) - set(WINGLET_PAIR) <= set(parsed)):
        return ()
    return tuple(p for p in POSITIONS if p in parsed)


def _check_metadata_lengths(raw: Mapping[str, Any], limits: DecodeLimits) -> None:
    lengths = {k: len(str(raw[k])) for k in METADATA_FIELDS if raw.get(k) is not None}
    long = {k: n for k, n in lengths.items() if n > limits.max_metadata_chars}
    if long:
        raise _long_metadata(long, limits)


def _long_metadata(lengths: dict[str, int], limits: DecodeLimits) -> FlightLogError:
    at_most = f"at most {limits.max_metadata_chars} characters"
    return FlightLogError([Issue("bad_metadata", "Metadata values are too long: "
                                 + ", ".join(f"{k} must be {at_most}" for k in lengths) + ".",
                                 {"fields": {k: at_most for k in lengths}, "lengths": lengths,
                                  "limit": "max_metadata_chars"})])


def _shallow_json(text: str, max_depth: int) -> Any:
    """``json.loads`` of a document nested at most ``max_depth`` deep; ValueError otherwise,
    found by a scan before parsing (deep nesting would exhaust the parser's recursion)."""
    if _json_depth(text) > max_depth:
        raise ValueError("nested too deep")
    try:
        return json.loads(text)
    except RecursionError:  # a bound above the interpreter's recursion limit
        raise ValueError("nested too deep") from None


def _json_depth(text: str) -> int:
    depth = deepest = 0
    in_string = escaped = False
    for ch in text:
        if in_string:
            if escaped:
                escaped = False
            elif ch == "\\":
                escaped = True
            elif ch == '"':
                in_string = False
        elif ch == '"':
            in_string = True
        elif ch in "[{":
            depth += 1
            deepest = max(deepest, depth)
        elif ch in "]}":
            depth -= 1
    return deepest


# --------------------------------------------------------------------------------------------
# Parquet
# --------------------------------------------------------------------------------------------


def stored_channels(log: FlightLog) -> dict[str, np.ndarray]:
    """``log``'s channels as format v1 stores them, in the file's column order: ``t`` float64,
    the signals float32 (an array already so is not copied). ValueError on a channel outside
    the format."""
    names = list(REQUIRED_CHANNELS) + [c for c in OPTIONAL_CHANNELS if c in log.channels]
    unknown = set(log.channels) - set(names)
    if unknown:
        raise ValueError(f"channels outside format v1: {sorted(unknown)}")
    return {n: np.ascontiguousarray(log.channels[n], dtype=np.float64 if n == "t" else np.float32)
            for n in names}


def write_parquet(log: FlightLog) -> bytes:
    """Encode ``log`` as canonical Parquet bytes (zstd). Same input, same bytes."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    channels = stored_channels(log)
    arrays = [pa.array(v) for v in channels.values()]
    names = list(channels)
    meta = {k.encode(): v.encode() for k, v in log.metadata.to_strings().items()}
    table = pa.Table.from_arrays(arrays, names=names).replace_schema_metadata(meta)
    sink = io.BytesIO()
    pq.write_table(table, sink, compression="zstd", compression_level=3, use_dictionary=False,
                   write_statistics=False, store_schema=True)
    return sink.getvalue()


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
    issues = _channel_set_issues(schema.names) + _parquet_dtype_issues(schema)
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
    _check_rows(channels["t"].shape[0], sum(v.itemsize for v in channels.values()), limits)
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
        raise _too_large("max_footer_bytes", limits.max_footer_bytes, footer,
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
        raise _too_large("max_columns", limits.max_columns, footer_meta.num_columns, "Columns")
    _check_rows(_parquet_rows(footer_meta), sum(_bytes_per_value(f.type) for f in schema),
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


def _check_rows(rows: int, row_bytes: int, limits: DecodeLimits) -> None:
    """Refuse ``rows`` samples per channel of ``row_bytes`` decoded per sample of all channels."""
    if rows > limits.max_samples_per_channel:
        raise _too_large("max_samples_per_channel", limits.max_samples_per_channel, rows,
                         "Samples per channel")
    if rows * row_bytes > limits.max_decoded_bytes:
        raise _too_large("max_decoded_bytes", limits.max_decoded_bytes, rows * row_bytes,
                         "Bytes of the decoded channels")


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


# --------------------------------------------------------------------------------------------
# CSV and MATLAB
# --------------------------------------------------------------------------------------------


def _channel_set_issues(names: list[str]) -> list[Issue]:
    issues = []
    present = set(names)
    missing = [c for c in REQUIRED_CHANNELS if c not in present]
    extra = sorted(present - set(REQUIRED_CHANNELS) - set(OPTIONAL_CHANNELS))
    if len(names) != len(present):
        issues.append(Issue("duplicate_channels", "Some channel names appear more than once.", {}))
    if missing:
        issues.append(Issue("missing_channels", f"{len(missing)} required channel(s) are missing: "
                            + ", ".join(missing[:6]) + ("..." if len(missing) > 6 else "") + ".",
                            {"missing": missing}))
    if extra:
        issues.append(Issue("extra_channels", "Channels not in format v1: "
                            + ", ".join(extra[:6]) + ("..." if len(extra) > 6 else "") + ".",
                            {"extra": extra}))
    return issues


def _canonical(columns: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    return {n: np.asarray(v, dtype=np.float64 if n == "t" else np.float32) for n, v in
            columns.items()}


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
        issues = _channel_set_issues(names)
        if issues:
            raise FlightLogError(issues)
        lines, returns = _scan_csv(_csv_bytes(data), limits)
        row_bytes = sum(8 if n == "t" else 4 for n in names)
        _check_rows(max(lines, returns) - 1, row_bytes, limits)  # below the header
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


def _csv_bytes(data: bytes) -> io.BufferedIOBase:
    """The CSV text as a binary stream, decompressed on the fly when gzip."""
    raw = io.BytesIO(data)
    return gzip.GzipFile(fileobj=raw, mode="rb") if data[:2] == _GZIP_MAGIC else raw


def _csv_header(stream: io.BufferedIOBase, limits: DecodeLimits) -> list[str]:
    line = stream.readline(limits.max_line_chars + 1)
    if len(line) > limits.max_line_chars:
        raise _too_large("max_line_chars", limits.max_line_chars, None,
                         "Characters of the CSV header line")
    names = [h.strip() for h in line.decode("utf-8").strip().split(",")]
    if len(names) > limits.max_columns:
        raise _too_large("max_columns", limits.max_columns, len(names), "Columns")
    return names


def _scan_csv(stream: io.BufferedIOBase, limits: DecodeLimits) -> tuple[int, int]:
    """``(lines, carriage returns)`` of the text (lines ended by a line feed or the end), read
    one chunk at a time; every line checked against ``max_line_chars`` and the whole against
    ``max_decompressed_bytes``."""
    total = line_feeds = returns = run = 0
    while chunk := stream.read(_CHUNK_BYTES):
        total += len(chunk)
        if total > limits.max_decompressed_bytes:
            raise _too_large("max_decompressed_bytes", limits.max_decompressed_bytes, None,
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
        raise _too_large("max_line_chars", limits.max_line_chars, None,
                         "Characters of a CSV line")
    return run


def _parse_csv(stream: io.BufferedIOBase, names: list[str], capacity: int,
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
            _check_rows(filled + len(values), sum(c.itemsize for c in columns.values()),
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


#: bytes per element of the numeric MATLAB classes (``scipy.io.whosmat`` names)
_MAT_NUMERIC = {"double": 8, "single": 4, "int8": 1, "uint8": 1, "int16": 2, "uint16": 2,
                "int32": 4, "uint32": 4, "int64": 8, "uint64": 8}


def read_mat(data: bytes, metadata: Mapping[str, Any],
             limits: DecodeLimits = DEFAULT_DECODE_LIMITS) -> FlightLog:
    """Decode a MATLAB v5 file holding one numeric vector per channel.

    MATLAB identifiers cannot hold '.', so ``WL1.ia`` may also be stored as ``WL1_ia``.
    Character variables named like metadata keys fill metadata the form did not give. Every
    variable's class and shape are checked from its header before anything is loaded, and a
    compressed variable is inflated here, in steps, to no more than its header allows (a header
    may lie about what its zlib stream holds); scipy then reads the inflated file.
    """
    import scipy.io

    elements = _mat_elements(data, limits)
    _check_mat_variables([e.variable for e in elements], limits)
    if any(e.compressed for e in elements):
        data = _inflated_mat5(data, elements)
    try:
        contents = scipy.io.loadmat(io.BytesIO(data), squeeze_me=True, chars_as_strings=True)
    except MemoryError:
        raise
    except Exception as exc:  # scipy raises many types on corrupt input
        raise _unreadable_mat(str(exc)) from None
    contents = {k: v for k, v in contents.items() if not k.startswith("__")}
    merged_meta = dict(metadata)
    columns: dict[str, np.ndarray] = {}
    for key, value in contents.items():
        if key in _REQUIRED_METADATA + _OPTIONAL_METADATA and isinstance(value, str):
            merged_meta.setdefault(key, value)
            continue
        name = key
        for p in POSITIONS:
            if key.startswith(p + "_"):
                name = p + "." + key[len(p) + 1:]
        arr = np.asarray(value)
        if arr.dtype.kind not in "fiu":
            raise FlightLogError([Issue("wrong_dtype", f"Variable '{key}' is not numeric.",
                                        {"variable": key, "found": str(arr.dtype)})])
        columns[name] = arr.ravel()
    meta = parse_metadata(merged_meta, limits)
    issues = _channel_set_issues(list(columns))
    lengths = {v.shape[0] for v in columns.values()}
    if not issues and len(lengths) != 1:
        issues.append(Issue("unreadable", "Channels have different lengths.",
                            {"lengths": sorted(lengths)}))
    if issues:
        raise FlightLogError(issues)
    return FlightLog(meta, _canonical(columns))


MatVariable = tuple[str, tuple[int, ...], str]  # name, shape, class as scipy.io.whosmat names it


class _MatElement(NamedTuple):
    """A variable of a MAT file and where its bytes are: ``data[start:end]`` is the zlib stream
    of a compressed (version 5) variable, else the whole element (version 4: unused)."""

    variable: MatVariable
    start: int = 0
    end: int = 0
    compressed: bool = False


def _mat_elements(data: bytes, limits: DecodeLimits) -> list[_MatElement]:
    """Every variable, from its header only.

    Version 5 files are walked here, inflating a few hundred bytes of each compressed variable
    (``scipy.io.whosmat`` inflates 128 KiB of compressed input per variable, which a file of
    zeros turns into up to 135 MB); version 4 files, never compressed, by whosmat.
    """
    import scipy.io

    try:
        if 0 not in data[:4]:  # scipy's test: a version 4 file starts with a zero byte
            return _mat5_elements(data, limits)
        return [_MatElement(v) for v in scipy.io.whosmat(io.BytesIO(data))]
    except (MemoryError, FlightLogError):
        raise
    except Exception as exc:  # scipy raises many types on corrupt input
        raise _unreadable_mat(str(exc)) from None


_MAT_CLASSES = {1: "cell", 2: "struct", 3: "object", 4: "char", 5: "sparse", 6: "double",
                7: "single", 8: "int8", 9: "uint8", 10: "int16", 11: "uint16", 12: "int32",
                13: "uint32", 14: "int64", 15: "uint64", 16: "function", 17: "opaque"}
_MI_MATRIX, _MI_COMPRESSED = 14, 15
_MAT_HEAD_BYTES = 512  # of a variable: its tag, array flags, dimensions and name
_MAT_CHAR_BYTES = 4  # a character stored as miUTF32, the widest a file may use
_INFLATE_STEP = 1 << 16  # compressed bytes fed to zlib at a time


def _mat5_elements(data: bytes, limits: DecodeLimits) -> list[_MatElement]:
    order = {b"IM": "<", b"MI": ">"}.get(data[126:128])
    if len(data) < 128 or order is None:
        raise _unreadable_mat("no MATLAB 5 header")
    if struct.unpack_from(order + "H", data, 124)[0] != 0x0100:
        raise _unreadable_mat("not a version 5 file (version 7.3 is HDF5, not supported)")
    view, at, found = memoryview(data), 128, []
    while at + 8 <= len(data):
        kind, size, body, after = _mat_tag(view, at, order)
        if body + size > len(data):
            raise _unreadable_mat("truncated variable")
        if kind == _MI_COMPRESSED:
            head, after = _inflated_head(view[body:body + size]), body + size
            found.append(_MatElement(_mat_matrix_header(head, order), body, after, True))
        elif kind == _MI_MATRIX:
            head = bytes(view[at:at + _MAT_HEAD_BYTES])
            found.append(_MatElement(_mat_matrix_header(head, order), at, min(after, len(data))))
        else:
            raise _unreadable_mat(f"unexpected data element type {kind}")
        if len(found) > limits.max_columns:
            raise _too_large("max_columns", limits.max_columns, None, "Variables")
        at = after
    return found


def _inflated_mat5(data: bytes, elements: list[_MatElement]) -> bytes:
    """The version 5 file ``data`` with its compressed variables inflated in place.

    Each is inflated in steps to at most what its header allows (its head, then one data
    element of its stated shape at its class's width; headers already checked against the
    limits): past that, 413 ``flight_too_large`` at once, whatever the stream holds."""
    parts, view = [data[:128]], memoryview(data)
    for (name, shape, mclass), start, end, compressed in elements:
        if not compressed:
            parts.append(view[start:end])
            continue
        width = _MAT_NUMERIC.get(mclass, _MAT_CHAR_BYTES)
        cap = _MAT_HEAD_BYTES + 16 + math.prod(shape) * width
        inflated = _inflate_at_most(view[start:end], cap)
        if inflated is None:
            shown = "x".join(map(str, shape))
            raise _too_large("max_decoded_bytes", cap, None, f"Inflated bytes of variable "
                             f"'{name}', whose header states {shown} {mclass}")
        parts += [inflated, bytes(-len(inflated) % 8)]
    return b"".join(parts)


def _inflate_at_most(compressed: memoryview, cap: int) -> bytearray | None:
    """The zlib stream ``compressed`` inflated, or None as soon as it yields more than ``cap``
    bytes (never more than ``cap`` + 1 of them in memory)."""
    inflater, out, fed = zlib.decompressobj(), bytearray(), 0
    pending: bytes | memoryview = b""
    while not inflater.eof:
        if not pending:
            if fed >= len(compressed):
                break  # a truncated stream: scipy reports the variable cut short
            pending, fed = compressed[fed:fed + _INFLATE_STEP], fed + _INFLATE_STEP
        out += inflater.decompress(pending, cap + 1 - len(out))
        if len(out) > cap:
            return None
        pending = inflater.unconsumed_tail
    return out


def _mat_tag(buf: Any, at: int, order: str) -> tuple[int, int, int, int]:
    """``(type, size, start of data, start of the next element)`` of the element at ``at``."""
    (first,) = struct.unpack_from(order + "I", buf, at)
    if first >> 16:  # small element: type and size in one word, data in the next
        return first & 0xFFFF, first >> 16, at + 4, at + 8
    kind, size = struct.unpack_from(order + "II", buf, at)
    return kind, size, at + 8, at + 8 + size + (-size % 8)


def _inflated_head(compressed: memoryview) -> bytes:
    """The first :data:`_MAT_HEAD_BYTES` of a compressed element, inflating no more."""
    inflater, head, fed = zlib.decompressobj(), b"", 0
    while len(head) < _MAT_HEAD_BYTES and fed < len(compressed) and not inflater.eof:
        head += inflater.decompress(compressed[fed:fed + 4096], _MAT_HEAD_BYTES - len(head))
        fed += 4096
    return head


def _mat_matrix_header(head: bytes, order: str) -> MatVariable:
    try:
        kind, size, at, _ = _mat_tag(head, 0, order)
        if kind != _MI_MATRIX or size == 0:
            raise _unreadable_mat("a variable is not a matrix")
        _, _, flags_at, at = _mat_tag(head, at, order)
        (flags,) = struct.unpack_from(order + "I", head, flags_at)
        _, dims_size, dims_at, at = _mat_tag(head, at, order)
        shape = struct.unpack_from(order + f"{dims_size // 4}i", head, dims_at)
        _, name_size, name_at, _ = _mat_tag(head, at, order)
        name = head[name_at:name_at + name_size].decode("latin1")
    except struct.error:
        raise _unreadable_mat("a variable header is cut short") from None
    if flags >> 11 & 1:
        return name, shape, "complex"
    return name, shape, "logical" if flags >> 9 & 1 else _MAT_CLASSES.get(flags & 0xFF, "unknown")


def _unreadable_mat(error: str) -> FlightLogError:
    return FlightLogError([Issue("unreadable", "The file is not a readable MATLAB v5 .mat file.",
                                 {"error": error[:300]})])


def _check_mat_variables(variables: list[tuple[str, tuple[int, ...], str]],
                         limits: DecodeLimits) -> None:
    """Refuse, before loading, too many variables, one too long, too many bytes in all, and
    classes that are neither numeric nor text (cells, structs, sparse, objects)."""
    if len(variables) > limits.max_columns:
        raise _too_large("max_columns", limits.max_columns, len(variables), "Variables")
    decoded = 0
    for name, shape, mclass in variables:
        size = math.prod(shape)
        if mclass == "char" and name in METADATA_FIELDS:
            if size > limits.max_metadata_chars:
                raise _long_metadata({name: size}, limits)
            continue
        if mclass not in _MAT_NUMERIC:
            raise FlightLogError([Issue("wrong_dtype", f"Variable '{name}' is not numeric.",
                                        {"variable": name, "found": mclass})])
        if size > limits.max_samples_per_channel:
            raise _too_large("max_samples_per_channel", limits.max_samples_per_channel, size,
                             f"Samples of variable '{name}'")
        decoded += size * _MAT_NUMERIC[mclass]
    if decoded > limits.max_decoded_bytes:
        raise _too_large("max_decoded_bytes", limits.max_decoded_bytes, decoded,
                         "Bytes of the decoded variables")


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


# --------------------------------------------------------------------------------------------
# coherence
# --------------------------------------------------------------------------------------------


def check_coherence(
    log: FlightLog,
    *,
    fleet_serials: Mapping[str, str] | None,
    limits: PhysicalLimits = DEFAULT_LIMITS,
) -> list[Issue]:
    """All coherence issues of a decoded log (empty list: the flight can be analysed).

    ``fleet_serials`` maps position -> serial installed on the aircraft; ``None`` means the
    aircraft is not registered.
    """
    issues: list[Issue] = []
    meta, ch = log.metadata, log.channels
    if fleet_serials is None:
        issues.append(Issue("unknown_aircraft", f"Aircraft '{meta.aircraft}' is not registered.",
                            {"aircraft": meta.aircraft}))
    else:
        wrong = {p: {"file": meta.actuator_serials.get(p), "installed": s}
                 for p, s in fleet_serials.items() if meta.actuator_serials.get(p) != s}
        if wrong:
            issues.append(Issue("serial_mismatch", "Actuator serials in the file do not match "
                                "those installed: " + ", ".join(sorted(wrong)) + ".",
                                {"positions": wrong}))

    n = log.n_samples
    bad_len = sorted(k for k, v in ch.items() if v.ndim != 1 or v.shape[0] != n)
    if bad_len:
        issues.append(Issue("unreadable", "Channels have different lengths.",
                            {"channels": bad_len}))
        return issues

    non_finite = sorted(k for k, v in ch.items() if not np.isfinite(v).all())
    if non_finite:
        issues.append(Issue("non_finite", f"{len(non_finite)} channel(s) hold NaN or infinite "
                            "values: " + ", ".join(non_finite[:6]) + ".",
                            {"channels": non_finite}))

    nominal_dt = 1.0 / NOMINAL_SAMPLE_RATE_HZ
    t = ch["t"]
    if n < 2:
        issues.append(Issue("too_short", "The recording has fewer than two samples.",
                            {"samples": n}))
        return issues
    dt = np.diff(t)
    finite_dt = dt[np.isfinite(dt)]
    if (finite_dt <= 0).any():
        first = int(np.argmax(dt <= 0))
        issues.append(Issue("time_not_monotonic", "Time does not increase strictly (first at "
                            f"sample {first + 1}).", {"first_index": first + 1}))
    gaps = np.flatnonzero(finite_dt > (limits.max_missed_samples + 1.5) * nominal_dt)
    if gaps.size:
        issues.append(Issue("time_gap", f"{gaps.size} gap(s) of more than "
                            f"{limits.max_missed_samples} missed samples (first at t = "
                            f"{float(t[gaps[0]]):.3f} s).", {"count": int(gaps.size),
                                                             "first_t_s": float(t[gaps[0]])}))
    duration = float(t[-1] - t[0]) if np.isfinite(t[[0, -1]]).all() else 0.0
    if duration > 0:
        measured = (n - 1) / duration
        for label, rate in (("measured", measured), ("declared", meta.sample_rate_hz)):
            if abs(rate / NOMINAL_SAMPLE_RATE_HZ - 1.0) > limits.sample_rate_tolerance:
                issues.append(Issue("sample_rate_off", f"The {label} sample rate {rate:.2f} Hz is "
                                    f"more than {limits.sample_rate_tolerance:.0%} off "
                                    f"{NOMINAL_SAMPLE_RATE_HZ:.0f} Hz.",
                                    {label + "_hz": rate, "nominal_hz": NOMINAL_SAMPLE_RATE_HZ}))
    if duration < limits.min_duration_s:
        issues.append(Issue("too_short", f"The recording lasts {duration:.2f} s; at least "
                            f"{limits.min_duration_s:.0f} s are needed for a feature window.",
                            {"duration_s": duration, "min_s": limits.min_duration_s}))

    with np.errstate(invalid="ignore"):
        over_current = sorted(
            f"{p}.{s}" for p in POSITIONS for s in ("ia", "ib", "ic")
            if np.nanmax(np.abs(ch[f"{p}.{s}"])) > limits.max_current_a)
        over_stroke = sorted(f"{p}.x" for p in POSITIONS
                             if np.nanmax(np.abs(ch[f"{p}.x"])) > limits.max_abs_position_m)
    if over_current:
        issues.append(Issue("current_out_of_range", "Phase currents beyond "
                            f"{limits.max_current_a:.1f} A (3x rated): " + ", ".join(over_current)
                            + ".", {"channels": over_current, "limit_a": limits.max_current_a}))
    if over_stroke:
        issues.append(Issue("position_out_of_range", "Rod positions beyond the stroke "
                            f"(+-{limits.max_abs_position_m * 1e3:.0f} mm): "
                            + ", ".join(over_stroke) + ".",
                            {"channels": over_stroke, "limit_m": limits.max_abs_position_m}))

    stuck = []
    for p in POSITIONS:
        spans = {s: float(np.ptp(ch[f"{p}.{s}"])) for s in SIGNALS}
        cmd = ch.get(f"{p}.x_cmd")
        commanded = (float(np.ptp(cmd)) > 0) if cmd is not None else any(spans.values())
        if commanded:
            stuck += [f"{p}.{s}" for s, span in spans.items() if span == 0.0]
    if stuck:
        issues.append(Issue("stuck_sensor", "Sensors that never change while the actuator is "
                            "commanded: " + ", ".join(stuck) + ".", {"channels": stuck}))
    return issues
