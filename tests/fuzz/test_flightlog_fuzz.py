"""Hypothesis on the flight-log readers: random, truncated and mutated bytes (and mutated
valid files) are either decoded or rejected with a clean :class:`FlightLogError` -- never any
other exception. Decoded logs also go through the coherence checks, which must not raise."""

from __future__ import annotations

import io
from functools import cache

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from server.flightlog import (
    FlightLog,
    FlightLogError,
    check_coherence,
    read_csv,
    read_mat,
    read_parquet,
)
from tests.flightlog_factory import make_log, serials_for

FUZZ = settings(max_examples=150, deadline=None, derandomize=True,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


@cache
def _valid_log() -> FlightLog:
    return make_log("FZ1", "F1", duration_s=0.5)


def _metadata() -> dict[str, str]:
    return _valid_log().metadata.to_strings()


@cache
def valid_parquet() -> bytes:
    from server.flightlog import write_parquet

    return write_parquet(_valid_log())


@cache
def valid_csv() -> bytes:
    log = _valid_log()
    names = list(log.channels)
    out = io.StringIO()
    np.savetxt(out, np.column_stack([log.channels[n] for n in names]), delimiter=",",
               fmt="%.7g", header=",".join(names), comments="")
    return out.getvalue().encode()


@cache
def valid_mat() -> bytes:
    import scipy.io

    out = io.BytesIO()
    scipy.io.savemat(out, {n.replace(".", "_"): v for n, v in _valid_log().channels.items()})
    return out.getvalue()


def _read(kind: str, data: bytes, metadata: dict[str, str]) -> FlightLog:
    if kind == "parquet":
        return read_parquet(data)
    if kind == "csv":
        return read_csv(data, metadata)
    return read_mat(data, metadata)


def _decode(kind: str, data: bytes, metadata: dict[str, str] | None = None) -> None:
    """Decoded, or rejected with a clean FlightLogError; the checks never raise."""
    try:
        log = _read(kind, data, _metadata() if metadata is None else metadata)
    except FlightLogError as exc:
        assert exc.issues and all(i.code for i in exc.issues)
        return
    check_coherence(log, fleet_serials=serials_for("FZ1"))
    check_coherence(log, fleet_serials=None)


VALID = {"parquet": valid_parquet, "csv": valid_csv, "mat": valid_mat}


@st.composite
def mutated(draw: st.DrawFn, original: bytes) -> bytes:
    data = bytearray(original)
    for _ in range(draw(st.integers(1, 6))):
        op = draw(st.sampled_from(["flip", "truncate", "insert", "delete", "splat"]))
        if not data:
            break
        pos = draw(st.integers(0, len(data) - 1))
        if op == "flip":
            data[pos] ^= draw(st.integers(1, 255))
        elif op == "truncate":
            del data[pos:]
        elif op == "insert":
            data[pos:pos] = draw(st.binary(min_size=1, max_size=16))
        elif op == "delete":
            del data[pos:pos + draw(st.integers(1, 64))]
        else:
            chunk = draw(st.binary(min_size=1, max_size=64))
            data[pos:pos + len(chunk)] = chunk
    return bytes(data)


@cache
def _long_log() -> FlightLog:
    # long enough for a feature window: a valid file must pass every coherence check
    return make_log("FZ1", "F2", duration_s=12.0)


@pytest.mark.parametrize("kind", ["parquet", "csv", "mat"])
def test_valid_files_decode_and_pass_every_check(kind: str) -> None:
    from server.flightlog import write_parquet

    original = _long_log()
    names = list(original.channels)
    if kind == "parquet":
        data = write_parquet(original)
    elif kind == "csv":
        out = io.StringIO()
        np.savetxt(out, np.column_stack([original.channels[n] for n in names]),
                   delimiter=",", fmt="%.9g", header=",".join(names), comments="")
        data = out.getvalue().encode()
    else:
        import scipy.io

        buf = io.BytesIO()
        scipy.io.savemat(buf, {n.replace(".", "_"): v for n, v in original.channels.items()})
        data = buf.getvalue()
    log = _read(kind, data, original.metadata.to_strings())  # a rejection fails the test
    assert set(log.channels) == set(names)
    for n in names:
        np.testing.assert_allclose(log.channels[n], original.channels[n], rtol=1e-6)
    assert check_coherence(log, fleet_serials=serials_for("FZ1")) == []


@pytest.mark.parametrize("kind", ["parquet", "csv", "mat"])
@FUZZ
@given(data=st.binary(max_size=4096))
def test_random_bytes_are_rejected_cleanly(kind: str, data: bytes) -> None:
    _decode(kind, data)


@pytest.mark.parametrize("kind", ["parquet", "csv", "mat"])
@FUZZ
@given(data=st.data())
def test_mutated_valid_files_are_rejected_cleanly(kind: str, data: st.DataObject) -> None:
    _decode(kind, data.draw(mutated(VALID[kind]())))


@pytest.mark.parametrize("kind", ["csv", "mat"])
@FUZZ
@given(metadata=st.dictionaries(
    st.sampled_from(["format", "aircraft", "flight", "started_at", "block_hours",
                     "sample_rate_hz", "actuator_serials", "source", "other"]),
    st.one_of(st.text(max_size=40), st.sampled_from(
        ["ema-flightlog/1", "nan", "inf", "-1", "1e308", "{}", "[]", "{\"WL1\": 1}",
         "2026-13-40T99:00:00Z", "FZ1", ""]))))
def test_mutated_metadata_is_rejected_cleanly(kind: str, metadata: dict[str, str]) -> None:
    _decode(kind, VALID[kind](), {**_metadata(), **metadata})
