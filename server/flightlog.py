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
import json
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from datetime import datetime, timezone
from typing import Any

import numpy as np

from server.vocabulary import POSITIONS

__all__ = [
    "FORMAT",
    "POSITIONS",
    "SIGNALS",
    "REQUIRED_CHANNELS",
    "OPTIONAL_CHANNELS",
    "METADATA_FIELDS",
    "NOMINAL_SAMPLE_RATE_HZ",
    "PhysicalLimits",
    "Issue",
    "FlightLogError",
    "FlightMetadata",
    "FlightLog",
    "write_parquet",
    "read_parquet",
    "read_parquet_metadata",
    "read_csv",
    "read_mat",
    "read_flightlog",
    "parse_metadata",
    "check_coherence",
]

FORMAT = "ema-flightlog/1"
SIGNALS: tuple[str, ...] = ("ia", "ib", "ic", "va", "vb", "vc", "theta", "x")
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
_OPTIONAL_METADATA = ("source",)
#: every metadata field of the format (Parquet key-value metadata, or upload form fields)
METADATA_FIELDS: tuple[str, ...] = _REQUIRED_METADATA + _OPTIONAL_METADATA
_MAX_ID_LEN = 64


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


def _valid_id(value: str) -> bool:
    return 0 < len(value) <= _MAX_ID_LEN and all(c.isalnum() or c in "-_." for c in value)


def parse_metadata(raw: Mapping[str, Any]) -> FlightMetadata:
    """Validate raw string metadata into :class:`FlightMetadata`.

    Raises :class:`FlightLogError` with ``unknown_format``, ``missing_metadata`` or
    ``bad_metadata`` issues.
    """
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
        if not _valid_id(value):
            bad[key] = "1-64 characters among letters, digits, '-', '_' and '.'"
    started_at = None
    try:
        started_at = datetime.fromisoformat(str(raw["started_at"]).replace("Z", "+00:00"))
        if started_at.tzinfo is None:
            bad["started_at"] = "ISO 8601 with a UTC offset"
    except ValueError:
        bad["started_at"] = "ISO 8601 with a UTC offset"
    numbers: dict[str, float] = {}
    for key in ("block_hours", "sample_rate_hz"):
        try:
            numbers[key] = float(raw[key])
            if not math.isfinite(numbers[key]) or numbers[key] <= 0:
                raise ValueError
        except (TypeError, ValueError):
            bad[key] = "a positive finite number"
    serials: dict[str, str] = {}
    try:
        parsed = raw["actuator_serials"]
        if isinstance(parsed, str):
            parsed = json.loads(parsed)
        if not isinstance(parsed, dict) or set(parsed) != set(POSITIONS):
            raise ValueError
        serials = {str(k): str(v) for k, v in parsed.items()}
        if not all(_valid_id(v) for v in serials.values()):
            raise ValueError
    except (TypeError, ValueError):
        bad["actuator_serials"] = 'a JSON object {"WL1": serial, "WL2": serial, "WT": serial}'
    source = raw.get("source")
    if source is not None and len(str(source)) > 200:
        bad["source"] = "at most 200 characters"
    if bad:
        raise FlightLogError([Issue("bad_metadata", "Metadata values are malformed: "
                                    + ", ".join(f"{k} must be {v}" for k, v in bad.items()) + ".",
                                    {"fields": bad})])
    assert started_at is not None
    return FlightMetadata(
        aircraft=aircraft,
        flight=flight,
        started_at=started_at.astimezone(timezone.utc),
        block_hours=numbers["block_hours"],
        sample_rate_hz=numbers["sample_rate_hz"],
        actuator_serials=serials,
        source=None if source is None else str(source),
    )


# --------------------------------------------------------------------------------------------
# Parquet
# --------------------------------------------------------------------------------------------


def write_parquet(log: FlightLog) -> bytes:
    """Encode ``log`` as canonical Parquet bytes (zstd). Same input, same bytes."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    names = list(REQUIRED_CHANNELS) + [c for c in OPTIONAL_CHANNELS if c in log.channels]
    unknown = set(log.channels) - set(names)
    if unknown:
        raise ValueError(f"channels outside format v1: {sorted(unknown)}")
    arrays = [
        pa.array(np.ascontiguousarray(log.channels[n],
                                      dtype=np.float64 if n == "t" else np.float32))
        for n in names
    ]
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


def read_parquet(data: bytes) -> FlightLog:
    """Decode Parquet bytes; raise :class:`FlightLogError` on anything that is not format v1."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    try:
        table = pq.read_table(io.BytesIO(data))
    except (pa.ArrowException, OSError, ValueError) as exc:
        raise FlightLogError([Issue("unreadable", "The file is not readable Parquet (truncated or "
                                    "corrupt).", {"error": str(exc)[:300]})]) from None
    raw_meta = {k.decode(errors="replace"): v.decode(errors="replace")
                for k, v in (table.schema.metadata or {}).items()}
    metadata = parse_metadata(raw_meta)
    issues = _channel_set_issues(table.column_names) + _parquet_dtype_issues(table.schema)
    if issues:
        raise FlightLogError(issues)
    try:
        channels = {name: table.column(name).to_numpy() for name in table.column_names}
    except (pa.ArrowException, ValueError) as exc:  # e.g. nulls in a column
        raise FlightLogError([Issue("non_finite", "A column holds missing (null) values.",
                                    {"error": str(exc)[:300]})]) from None
    return FlightLog(metadata=metadata, channels=channels)


def read_parquet_metadata(path: str | os.PathLike[str]) -> FlightMetadata | None:
    """The metadata of a flight-log Parquet file, read from its footer only and validated as
    an upload's are (:func:`parse_metadata`); None for a file without metadata."""
    import pyarrow.parquet as pq

    raw = pq.read_schema(path).metadata or {}
    if not raw:
        return None
    return parse_metadata({k.decode(errors="replace"): v.decode(errors="replace")
                           for k, v in raw.items()})


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


def read_csv(data: bytes, metadata: Mapping[str, Any]) -> FlightLog:
    """Decode CSV (gzip detected by its magic bytes) with a header row of channel names."""
    meta = parse_metadata(metadata)
    try:
        if data[:2] == b"\x1f\x8b":
            data = gzip.decompress(data)
        text = data.decode("utf-8")
    except (OSError, EOFError, UnicodeDecodeError, gzip.BadGzipFile) as exc:
        raise FlightLogError([Issue("unreadable", "The CSV file is not readable text (bad gzip "
                                    "or encoding).", {"error": str(exc)[:300]})]) from None
    header, _, body = text.partition("\n")
    names = [h.strip() for h in header.strip().split(",")]
    issues = _channel_set_issues(names)
    if issues:
        raise FlightLogError(issues)
    try:
        values = np.loadtxt(io.StringIO(body), delimiter=",", dtype=np.float64, ndmin=2)
    except ValueError as exc:
        raise FlightLogError([Issue("unreadable", "The CSV body has rows that are not numbers or "
                                    "have the wrong number of fields.", {"error": str(exc)[:300]})
                              ]) from None
    if values.shape[0] == 0 or values.shape[1] != len(names):
        raise FlightLogError([Issue("unreadable", "The CSV file has no data rows.", {})])
    return FlightLog(meta, _canonical({n: values[:, i] for i, n in enumerate(names)}))


def read_mat(data: bytes, metadata: Mapping[str, Any]) -> FlightLog:
    """Decode a MATLAB v5 file holding one numeric vector per channel.

    MATLAB identifiers cannot hold '.', so ``WL1.ia`` may also be stored as ``WL1_ia``.
    Character variables named like metadata keys fill metadata the form did not give.
    """
    import scipy.io

    try:
        contents = scipy.io.loadmat(io.BytesIO(data), squeeze_me=True, chars_as_strings=True)
    except Exception as exc:  # scipy raises many types on corrupt input
        raise FlightLogError([Issue("unreadable", "The file is not a readable MATLAB v5 .mat "
                                    "file.", {"error": str(exc)[:300]})]) from None
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
    meta = parse_metadata(merged_meta)
    issues = _channel_set_issues(list(columns))
    lengths = {v.shape[0] for v in columns.values()}
    if not issues and len(lengths) != 1:
        issues.append(Issue("unreadable", "Channels have different lengths.",
                            {"lengths": sorted(lengths)}))
    if issues:
        raise FlightLogError(issues)
    return FlightLog(meta, _canonical(columns))


def read_flightlog(data: bytes, *, kind: str, metadata: Mapping[str, Any] | None = None
                   ) -> FlightLog:
    """Decode ``data`` of ``kind`` ``parquet`` | ``csv`` | ``mat``."""
    if kind == "parquet":
        return read_parquet(data)
    if kind == "csv":
        return read_csv(data, metadata or {})
    if kind == "mat":
        return read_mat(data, metadata or {})
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
