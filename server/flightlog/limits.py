"""How far a recording may go (physics) and what a reader may build from untrusted bytes.

The refusals past a decode limit are built here, so that every reader names a limit the same
way, and so are the bounds on the reasons a rejection stores and echoes.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

from server.flightlog.format import FlightLogError, Issue


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


def too_large(limit: str, maximum: int, found: int | None, what: str) -> FlightLogError:
    """``what`` went past ``limit`` (a :class:`DecodeLimits` field); ``found`` None: unknown
    beyond the limit (the reader stopped there)."""
    amount = f"more than {maximum}" if found is None else f"{found}, more than {maximum}"
    return FlightLogError([Issue("too_large", f"{what}: {amount} (limit {limit}).",
                                 {"limit": limit, "maximum": maximum, "found": found})])


def check_rows(rows: int, row_bytes: int, limits: DecodeLimits) -> None:
    """Refuse ``rows`` samples per channel of ``row_bytes`` decoded per sample of all channels."""
    if rows > limits.max_samples_per_channel:
        raise too_large("max_samples_per_channel", limits.max_samples_per_channel, rows,
                         "Samples per channel")
    if rows * row_bytes > limits.max_decoded_bytes:
        raise too_large("max_decoded_bytes", limits.max_decoded_bytes, rows * row_bytes,
                         "Bytes of the decoded channels")


def long_metadata(lengths: dict[str, int], limits: DecodeLimits) -> FlightLogError:
    at_most = f"at most {limits.max_metadata_chars} characters"
    return FlightLogError([Issue("bad_metadata", "Metadata values are too long: "
                                 + ", ".join(f"{k} must be {at_most}" for k in lengths) + ".",
                                 {"fields": {k: at_most for k in lengths}, "lengths": lengths,
                                  "limit": "max_metadata_chars"})])


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
