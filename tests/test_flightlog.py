"""Flight-log format v1: round trips, determinism, the metadata rules, and the readers' limits
on hostile files (docs/SECURITY.md, "Hostile uploads")."""

from __future__ import annotations

import gzip
import io
import json
import tracemalloc
from collections.abc import Callable

import numpy as np
import pytest
import scipy.io

from server.config import Settings
from server.flightlog import (
    DEFAULT_DECODE_LIMITS,
    REQUIRED_CHANNELS,
    DecodeLimits,
    FlightLog,
    FlightLogError,
    Issue,
    bounded_reasons,
    check_coherence,
    parse_metadata,
    read_csv,
    read_mat,
    read_parquet,
    read_parquet_decimated,
    write_parquet,
)
from tests.bombs import gzip_csv_bomb, long_header_csv, mat_bomb, nested_json, plain_csv
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


def test_active_channels_are_optional_and_read_in_position_order() -> None:
    """An active-standby download names its active drives; a log without the field (every
    drive active) reads as before."""
    raw = make_log().metadata.to_strings()
    assert "active_channels" not in raw and parse_metadata(raw).active_channels is None
    assert parse_metadata({**raw, "active_channels": '["WT", "WL2"]'}).active_channels == (
        "WL2", "WT")


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
    ("active_channels", '["WL1", "WL2"]', "bad_metadata"),  # the wingtip undriven
    ("active_channels", '["WT"]', "bad_metadata"),  # the winglet undriven
    ("active_channels", '["WL1", "WL1", "WT"]', "bad_metadata"),
    ("active_channels", '["WL3", "WT"]', "bad_metadata"),
    ("active_channels", '"WL1"', "bad_metadata"),
    ("active_channels", "WL1,WT", "bad_metadata"),
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


# --------------------------------------------------------------------------------------------
# limits on what a reader builds (DecodeLimits)
# --------------------------------------------------------------------------------------------

LOG = make_log()  # 9600 samples of 29 channels
META = LOG.metadata.to_strings()
ROW_BYTES = 8 + 4 * (len(LOG.channels) - 1)  # t float64, signals float32


def _refused(read: Callable[[], object]) -> Issue:
    with pytest.raises(FlightLogError) as err:
        read()
    return err.value.issues[0]


def _too_large(read: Callable[[], object], limit: str) -> None:
    issue = _refused(read)
    assert issue.code == "too_large" and issue.details["limit"] == limit, issue
    assert _json_size(issue) < 300


def _json_size(issue: Issue) -> int:
    return len(json.dumps(issue.as_dict()))


def _peak_bytes(read: Callable[[], object]) -> int:
    """Peak of the Python allocations (numpy's included) while ``read`` runs."""
    tracemalloc.start()
    try:
        try:
            read()
        except FlightLogError:
            pass
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def test_the_settings_give_the_readers_their_limits() -> None:
    assert Settings().decode_limits == DecodeLimits() == DEFAULT_DECODE_LIMITS
    assert Settings(max_decoded_bytes=5).decode_limits.max_decoded_bytes == 5


def test_parquet_size_is_checked_from_the_footer_before_any_column() -> None:
    data = write_parquet(LOG)
    footer = int.from_bytes(data[-8:-4], "little")
    # data pages zeroed: reading any column would find the file corrupt
    hollow = data[:4] + bytes(len(data) - footer - 12) + data[-footer - 8:]
    assert _refused(lambda: read_parquet(hollow)).code == "unreadable"
    n = LOG.n_samples
    for limits, limit in ((DecodeLimits(max_samples_per_channel=n - 1), "max_samples_per_channel"),
                          (DecodeLimits(max_decoded_bytes=n * ROW_BYTES - 1), "max_decoded_bytes"),
                          (DecodeLimits(max_columns=len(LOG.channels) - 1), "max_columns"),
                          (DecodeLimits(max_footer_bytes=footer - 1), "max_footer_bytes")):
        _too_large(lambda limits=limits: read_parquet(hollow, limits), limit)
    at_the_limits = DecodeLimits(max_samples_per_channel=n, max_decoded_bytes=n * ROW_BYTES,
                                 max_columns=len(LOG.channels), max_footer_bytes=footer)
    assert read_parquet(data, at_the_limits).n_samples == n


def test_parquet_decimated_while_read_keeps_every_nth_sample() -> None:
    log = make_log(duration_s=100.0)  # 80,000 samples: two batches, the second not aligned
    data = write_parquet(log)
    step, signals = read_parquet_decimated(data, None, 1000)
    assert step == 80 and set(signals) == set(log.channels)
    for name, values in signals.items():
        assert np.array_equal(values, log.channels[name].astype(values.dtype)[::step]), name
    step, signals = read_parquet_decimated(data, ["WL2.x"], 100_000)
    assert step == 1 and set(signals) == {"t", "WL2.x"} and signals["t"].size == 80_000
    unknown = _refused(lambda: read_parquet_decimated(data, ["WL2.x", "WL9.x"], 100))
    assert unknown.code == "unknown_channel" and unknown.details["channels"] == ["WL9.x"]


def test_csv_is_streamed_and_parsed_into_the_canonical_types() -> None:
    text = plain_csv(LOG.channels)
    for data in (text, gzip.compress(text), text.replace(b"\n", b"\r\n")):
        log = read_csv(data, META)
        assert log.n_samples == LOG.n_samples
        for name, values in LOG.channels.items():
            assert log.channels[name].dtype == (np.float64 if name == "t" else np.float32)
            assert np.allclose(log.channels[name], values, rtol=1e-6, atol=1e-6), name


def test_csv_limits() -> None:
    text = plain_csv(LOG.channels)
    n = LOG.n_samples
    header = text.partition(b"\n")[0]
    for data, limits, limit in (
            (gzip.compress(text), DecodeLimits(max_decompressed_bytes=len(text) - 1),
             "max_decompressed_bytes"),
            (text, DecodeLimits(max_samples_per_channel=n - 1), "max_samples_per_channel"),
            (text, DecodeLimits(max_decoded_bytes=n * ROW_BYTES - 1), "max_decoded_bytes"),
            (text, DecodeLimits(max_columns=len(LOG.channels) - 1), "max_columns"),
            (long_header_csv(10_000), DEFAULT_DECODE_LIMITS, "max_line_chars"),
            (header + b"\n" + b"0," * 3000 + b"0\n", DEFAULT_DECODE_LIMITS, "max_line_chars")):
        _too_large(lambda data=data, limits=limits: read_csv(data, META, limits), limit)
    at_the_limits = DecodeLimits(max_samples_per_channel=n, max_decoded_bytes=n * ROW_BYTES)
    assert read_csv(text, META, at_the_limits).n_samples == n


def test_gzip_csv_bomb_is_decompressed_as_a_stream_under_a_cap() -> None:
    bomb = gzip_csv_bomb(list(LOG.channels), 272 << 20)  # past the default 256 MiB
    assert len(bomb) < 1 << 20
    _too_large(lambda: read_csv(bomb, META), "max_decompressed_bytes")
    assert _peak_bytes(lambda: read_csv(bomb, META)) < 16 << 20


def test_mat_variables_are_checked_from_their_headers_before_loading() -> None:
    out = io.BytesIO()
    scipy.io.savemat(out, {n.replace(".", "_"): v for n, v in LOG.channels.items()},
                     do_compression=True)
    data, n = out.getvalue(), LOG.n_samples
    assert read_mat(data, META).n_samples == n
    mat_bytes = sum(v.size * v.itemsize for v in LOG.channels.values())  # as saved
    for limits, limit in ((DecodeLimits(max_samples_per_channel=n - 1), "max_samples_per_channel"),
                          (DecodeLimits(max_decoded_bytes=mat_bytes - 1), "max_decoded_bytes"),
                          (DecodeLimits(max_columns=len(LOG.channels) - 1), "max_columns")):
        _too_large(lambda limits=limits: read_mat(data, META, limits), limit)
    bomb = mat_bomb("t", 40_000_000)  # 320 MB of doubles in 1.4 MB
    _too_large(lambda: read_mat(bomb, META), "max_samples_per_channel")
    assert _peak_bytes(lambda: read_mat(bomb, META)) < 4 << 20


def test_mat_variable_inflating_past_its_header_is_refused_while_inflating() -> None:
    """A header stating 1 x 10 over a zlib stream of 10^8 doubles (760 KiB sent): scipy
    trusted the element sizes and inflated 800 MB before failing to reshape."""
    liar = mat_bomb("t", 100_000_000, declared=10, level=9)
    _too_large(lambda: read_mat(liar, META), "max_decoded_bytes")
    assert _refused(lambda: read_mat(liar, META)).details["maximum"] < 1024  # 1 x 10 doubles
    assert _peak_bytes(lambda: read_mat(liar, META)) < 4 << 20


@pytest.mark.parametrize("variable,code", [
    (np.array([[1, 2]], dtype=object), "wrong_dtype"),  # a cell array: never loaded
    (np.array([1 + 2j]), "wrong_dtype"),
    ("x" * 5000, "bad_metadata"),  # a metadata variable past max_metadata_chars
])
def test_mat_variables_of_other_classes_are_refused_before_loading(variable: object,
                                                                  code: str) -> None:
    out = io.BytesIO()
    name = "source" if isinstance(variable, str) else "bogus"
    scipy.io.savemat(out, {"t": np.arange(3.0), name: variable})
    assert _refused(lambda: read_mat(out.getvalue(), META)).code == code


@pytest.mark.parametrize("value,limits", [
    (nested_json(5000), DEFAULT_DECODE_LIMITS),  # 10 KB: past max_metadata_chars
    (nested_json(500), DEFAULT_DECODE_LIMITS),  # 1000 characters: past max_json_depth
    (nested_json(100_000), DecodeLimits(max_metadata_chars=10**6, max_json_depth=10**6)),
])
def test_nested_serials_are_bad_metadata_never_a_recursion_error(value: str,
                                                                 limits: DecodeLimits) -> None:
    raw = {**META, "actuator_serials": value}
    issue = _refused(lambda: parse_metadata(raw, limits))
    assert issue.code == "bad_metadata" and "actuator_serials" in issue.details["fields"]


def test_long_metadata_values_are_refused_without_being_quoted() -> None:
    for field in ("format", "aircraft", "source", "started_at"):
        issue = _refused(lambda field=field: parse_metadata({**META, field: "x" * 10**6}))
        assert issue.code == "bad_metadata" and issue.details["fields"] == {
            field: "at most 1024 characters"}
        assert _json_size(issue) < 500


def test_reasons_are_bounded_in_number_and_size() -> None:
    names = [f"extra_channel_{i}" for i in range(100_000)]
    reasons = [{"code": "extra_channels", "message": "x" * 10**6, "details": {"extra": names}}]
    kept = bounded_reasons(reasons * 50)
    assert len(kept) == 20 and kept[-1] == {"code": "more_reasons",
                                            "message": "31 more reasons not shown.",
                                            "details": {"count": 31}}
    assert all(len(json.dumps(r)) <= 2048 for r in kept)
    assert kept[0]["details"]["truncated"] is True
    assert kept[0]["details"]["extra"] == names[:8]
    small = [Issue("too_short", "Short.", {"samples": 3}).as_dict()]
    assert bounded_reasons(small) == small
