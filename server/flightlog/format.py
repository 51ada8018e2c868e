"""What format v1 is: its channels, its metadata fields, a decoded flight and a problem found.

The vocabulary every other module of the package speaks; it imports none of them.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass, field
from datetime import datetime, timezone
from typing import Any

import numpy as np

from server.vocabulary import POSITIONS, SIGNALS

FORMAT = "ema-flightlog/1"
NOMINAL_SAMPLE_RATE_HZ = 800.0
REQUIRED_CHANNELS: tuple[str, ...] = ("t",) + tuple(f"{p}.{s}" for p in POSITIONS for s in SIGNALS)
OPTIONAL_CHANNELS: tuple[str, ...] = tuple(f"{p}.x_cmd" for p in POSITIONS) + (
    "T_amb",
    "surf_WL",
    "surf_WT",
)
REQUIRED_METADATA = (
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
OPTIONAL_METADATA = ("source", "active_channels")
#: every metadata field of the format (Parquet key-value metadata, or upload form fields)
METADATA_FIELDS: tuple[str, ...] = REQUIRED_METADATA + OPTIONAL_METADATA
MAX_ID_LEN = 64
#: longest block time of one flight [h]: a day; beyond it a value is a unit or typing error
MAX_BLOCK_HOURS = 24.0
#: tails, flight codes and serials: ASCII letters, digits, '.', '_', '-', not only dots ('..'
#: would name a parent directory wherever an id becomes a path segment)
ID_PATTERN = r"^[A-Za-z0-9._-]*[A-Za-z0-9_-][A-Za-z0-9._-]*$"
_ID_RE = re.compile(ID_PATTERN)


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


def valid_id(value: str) -> bool:
    return len(value) <= MAX_ID_LEN and _ID_RE.fullmatch(value) is not None


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


def channel_set_issues(names: list[str]) -> list[Issue]:
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
