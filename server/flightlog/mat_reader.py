"""MATLAB v5 ``.mat`` uploads, every variable checked from its header before it is loaded."""

from __future__ import annotations

import io
import math
import struct
import zlib
from collections.abc import Mapping
from typing import Any, NamedTuple

import numpy as np

from server.flightlog.format import (
    METADATA_FIELDS,
    FlightLog,
    FlightLogError,
    Issue,
    channel_set_issues,
)
from server.flightlog.limits import (
    DEFAULT_DECODE_LIMITS,
    DecodeLimits,
    long_metadata,
    too_large,
)
from server.flightlog.metadata import parse_metadata
from server.vocabulary import POSITIONS

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
        if key in METADATA_FIELDS and isinstance(value, str):
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
    issues = channel_set_issues(list(columns))
    lengths = {v.shape[0] for v in columns.values()}
    if not issues and len(lengths) != 1:
        issues.append(Issue("unreadable", "Channels have different lengths.",
                            {"lengths": sorted(lengths)}))
    if issues:
        raise FlightLogError(issues)
    return FlightLog(meta, _canonical(columns))


def _canonical(columns: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    return {n: np.asarray(v, dtype=np.float64 if n == "t" else np.float32) for n, v in
            columns.items()}


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
            raise too_large("max_columns", limits.max_columns, None, "Variables")
        at = after
    return found


def _inflated_mat5(data: bytes, elements: list[_MatElement]) -> bytes:
    """The version 5 file ``data`` with its compressed variables inflated in place.

    Each is inflated in steps to at most what its header allows (its head, then one data
    element of its stated shape at its class's width; headers already checked against the
    limits): past that, 413 ``flight_too_large`` at once, whatever the stream holds."""
    parts: list[bytes | bytearray | memoryview] = [data[:128]]
    view = memoryview(data)
    for (name, shape, mclass), start, end, compressed in elements:
        if not compressed:
            parts.append(view[start:end])
            continue
        width = _MAT_NUMERIC.get(mclass, _MAT_CHAR_BYTES)
        cap = _MAT_HEAD_BYTES + 16 + math.prod(shape) * width
        inflated = _inflate_at_most(view[start:end], cap)
        if inflated is None:
            shown = "x".join(map(str, shape))
            raise too_large("max_decoded_bytes", cap, None, f"Inflated bytes of variable "
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
        raise too_large("max_columns", limits.max_columns, len(variables), "Variables")
    decoded = 0
    for name, shape, mclass in variables:
        size = math.prod(shape)
        if mclass == "char" and name in METADATA_FIELDS:
            if size > limits.max_metadata_chars:
                raise long_metadata({name: size}, limits)
            continue
        if mclass not in _MAT_NUMERIC:
            raise FlightLogError([Issue("wrong_dtype", f"Variable '{name}' is not numeric.",
                                        {"variable": name, "found": mclass})])
        if size > limits.max_samples_per_channel:
            raise too_large("max_samples_per_channel", limits.max_samples_per_channel, size,
                             f"Samples of variable '{name}'")
        decoded += size * _MAT_NUMERIC[mclass]
    if decoded > limits.max_decoded_bytes:
        raise too_large("max_decoded_bytes", limits.max_decoded_bytes, decoded,
                         "Bytes of the decoded variables")
