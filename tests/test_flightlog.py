"""Flight-log format v1: round trips, determinism, and the metadata rules."""

from __future__ import annotations

import numpy as np
import pytest

from server.flightlog import (
    REQUIRED_CHANNELS,
    FlightLog,
    FlightLogError,
    check_coherence,
    parse_metadata,
    read_parquet,
    write_parquet,
)
from tests.flightlog_factory import make_log, serials_for


def test_parquet_round_trip_is_exact_and_deterministic() -> None:
    log = make_log("A1", "F1")
    data = write_parquet(log)
    assert data == write_parquet(make_log("A1", "F1"))
    back = read_parquet(data)
    assert back.metadata == log.metadata
    for name in REQUIRED_CHANNELS:
        expected_dtype = np.float64 if name == "t" else np.float32
        assert back.channels[name].dtype == expected_dtype
        assert np.array_equal(back.channels[name], log.channels[name].astype(expected_dtype))
    assert check_coherence(back, fleet_serials=serials_for("A1")) == []


def test_writer_refuses_channels_outside_the_format() -> None:
    log = make_log()
    with pytest.raises(ValueError, match="outside format"):
        write_parquet(FlightLog(log.metadata, {**log.channels, "bogus": np.zeros(3)}))


@pytest.mark.parametrize("field,value,code", [
    ("format", "other/1", "unknown_format"),
    ("flight", "", "missing_metadata"),
    ("started_at", "2026-05-01T08:00:00", "bad_metadata"),  # no UTC offset
    ("actuator_serials", '{"WL1": "a"}', "bad_metadata"),
    ("aircraft", "../../etc", "bad_metadata"),
    ("sample_rate_hz", "nan", "bad_metadata"),
])
def test_metadata_rules(field: str, value: str, code: str) -> None:
    raw = make_log().metadata.to_strings()
    raw[field] = value
    with pytest.raises(FlightLogError) as err:
        parse_metadata(raw)
    assert err.value.issues[0].code == code
    assert err.value.issues[0].message


def test_declared_sample_rate_checked() -> None:
    log = make_log()
    raw = log.metadata.to_strings()
    raw["sample_rate_hz"] = "1000"
    bad = FlightLog(parse_metadata(raw), log.channels)
    codes = [i.code for i in check_coherence(bad, fleet_serials=serials_for("T001"))]
    assert codes == ["sample_rate_off"]
