"""The canonical encoding: Parquet, zstd, the same bytes for the same log."""

from __future__ import annotations

import io

from server.flightlog.format import FlightLog, stored_channels


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
