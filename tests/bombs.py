"""Hostile flight logs, small to send and large once decoded, built in bounded memory: each is
a few hundred KB to a few MB however far it expands (docs/SECURITY.md, "Hostile uploads")."""

from __future__ import annotations

import gzip
import io
import struct
import zlib
from collections.abc import Mapping

import numpy as np

__all__ = ["gzip_csv_bomb", "parquet_bomb", "mat_bomb", "nested_json", "long_header_csv",
           "plain_csv"]

_MIB = 1 << 20


def gzip_csv_bomb(names: list[str], expanded_bytes: int) -> bytes:
    """A gzip CSV (a header, then rows of zeros) that decompresses to ``expanded_bytes`` or a
    little more: one 16 MiB gzip member repeated (a gzip file may hold many members)."""
    row = (",".join(["0"] * len(names)) + "\n").encode()
    member = gzip.compress(row * (16 * _MIB // len(row)), compresslevel=6, mtime=0)
    repeats = -(-expanded_bytes // (16 * _MIB))
    return gzip.compress((",".join(names) + "\n").encode(), mtime=0) + member * repeats


def parquet_bomb(metadata: Mapping[str, str], names: list[str], rows: int) -> bytes:
    """A format-v1 Parquet file of ``rows`` rows of zeros (t float64, signals float32), written
    one row group of 2^20 rows at a time from the same arrays."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    group = min(rows, 1 << 20)
    zeros = {np.float64: pa.array(np.zeros(group)), np.float32: pa.array(np.zeros(group,
                                                                                 np.float32))}
    schema = pa.schema([(n, pa.float64() if n == "t" else pa.float32()) for n in names],
                       metadata={k.encode(): v.encode() for k, v in metadata.items()})
    sink = io.BytesIO()
    with pq.ParquetWriter(sink, schema, compression="zstd", use_dictionary=False,
                          write_statistics=False) as writer:
        for start in range(0, rows, group):
            size = min(group, rows - start)
            writer.write_table(pa.Table.from_arrays(
                [zeros[np.float64 if n == "t" else np.float32].slice(0, size) for n in names],
                schema=schema))
    return sink.getvalue()


def mat_bomb(name: str, n: int, declared: int | None = None, level: int = 1) -> bytes:
    """A MATLAB v5 file holding one zlib-compressed double vector of ``n`` zeros, written by
    hand so that the vector is never in memory. ``declared``: the length its header states
    (1 x ``declared``) when that is a lie; the element sizes still tell the truth, as a
    reader that trusts them would need. ``level``: zlib's (9 packs the zeros ~1000:1)."""
    header = (b"MATLAB 5.0 MAT-file, written by tests/bombs.py".ljust(116, b" ") + b"\0" * 8
              + struct.pack("<H", 0x0100) + b"IM")
    label = name.encode()
    body = (struct.pack("<IIII", 6, 8, 6, 0)  # array flags (miUINT32): class mxDOUBLE
            + struct.pack("<IIii", 5, 8, 1, n if declared is None else declared)  # 1 x n
            + struct.pack("<II", 1, len(label)) + label + b"\0" * (-len(label) % 8)
            + struct.pack("<II", 9, 8 * n))  # real part (miDOUBLE), its data follows
    packer = zlib.compressobj(level)
    parts = [packer.compress(struct.pack("<II", 14, len(body) + 8 * n) + body)]
    chunk = bytes(8 * _MIB)
    left = 8 * n
    while left:
        parts.append(packer.compress(chunk[:min(left, len(chunk))]))
        left -= min(left, len(chunk))
    parts.append(packer.flush())
    packed = b"".join(parts)
    return header + struct.pack("<II", 15, len(packed)) + packed  # miCOMPRESSED


def nested_json(depth: int) -> str:
    """``[[[...]]]``: ``depth`` arrays, one inside the other."""
    return "[" * depth + "]" * depth


def long_header_csv(chars: int) -> bytes:
    """A CSV whose header line alone holds ``chars`` characters of column names."""
    names = ",".join(f"c{i:07d}" for i in range(chars // 9 + 1))
    return names[:chars].encode() + b"\n0\n"


def plain_csv(channels: Mapping[str, np.ndarray]) -> bytes:
    """``channels`` as CSV text with a header row, the way an upload client writes it."""
    names = list(channels)
    out = io.StringIO()
    np.savetxt(out, np.column_stack([channels[n] for n in names]), delimiter=",",
               header=",".join(names), comments="", fmt="%.9g")
    return out.getvalue().encode()
