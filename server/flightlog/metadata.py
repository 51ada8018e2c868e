"""Flight-level metadata validated from strings (Parquet footer or upload form fields)."""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from datetime import datetime, timezone
from typing import Any

from server.flightlog.format import (
    FORMAT,
    MAX_BLOCK_HOURS,
    METADATA_FIELDS,
    REQUIRED_METADATA,
    FlightLogError,
    FlightMetadata,
    Issue,
    valid_id,
)
from server.flightlog.limits import DEFAULT_DECODE_LIMITS, DecodeLimits, long_metadata
from server.vocabulary import POSITIONS, WINGLET_PAIR


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
    missing = [k for k in REQUIRED_METADATA if k != "format" and raw.get(k) in (None, "")]
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
        raise long_metadata(long, limits)


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
