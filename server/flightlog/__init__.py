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
human sentence; a file may have several. This package imports nothing of ours but the shared
vocabulary, so the simulator can use it (``sim_worker`` writes, ``server`` reads and checks).

One module per job: :mod:`.format` (channels, metadata fields, the decoded log), :mod:`.limits`
(physical and decode limits), :mod:`.metadata`, :mod:`.readers` (with :mod:`.csv_reader` and
:mod:`.mat_reader`), :mod:`.writer` and :mod:`.coherence`. Import the public names from here.
"""

from server.flightlog.coherence import check_coherence
from server.flightlog.csv_reader import read_csv
from server.flightlog.format import (
    FORMAT,
    ID_PATTERN,
    MAX_BLOCK_HOURS,
    MAX_ID_LEN,
    METADATA_FIELDS,
    NOMINAL_SAMPLE_RATE_HZ,
    OPTIONAL_CHANNELS,
    REQUIRED_CHANNELS,
    FlightLog,
    FlightLogError,
    FlightMetadata,
    Issue,
    stored_channels,
    valid_id,
)
from server.flightlog.limits import (
    DEFAULT_DECODE_LIMITS,
    DecodeLimits,
    PhysicalLimits,
    bounded_reasons,
)
from server.flightlog.mat_reader import read_mat
from server.flightlog.metadata import parse_metadata
from server.flightlog.readers import (
    read_back,
    read_flightlog,
    read_parquet,
    read_parquet_decimated,
    read_parquet_metadata,
)
from server.flightlog.writer import write_parquet
from server.vocabulary import POSITIONS, SIGNALS

__all__ = [
    "FORMAT",
    "POSITIONS",
    "SIGNALS",
    "REQUIRED_CHANNELS",
    "OPTIONAL_CHANNELS",
    "METADATA_FIELDS",
    "ID_PATTERN",
    "MAX_ID_LEN",
    "MAX_BLOCK_HOURS",
    "valid_id",
    "NOMINAL_SAMPLE_RATE_HZ",
    "PhysicalLimits",
    "DecodeLimits",
    "DEFAULT_DECODE_LIMITS",
    "Issue",
    "FlightLogError",
    "FlightMetadata",
    "FlightLog",
    "stored_channels",
    "write_parquet",
    "read_parquet",
    "read_back",
    "read_parquet_metadata",
    "read_parquet_decimated",
    "read_csv",
    "read_mat",
    "read_flightlog",
    "parse_metadata",
    "check_coherence",
    "bounded_reasons",
]

# A failed job stores the error's qualified name (server/jobs/worker.py): the public one, as
# before the module became a package, not the module that happens to define it.
FlightLogError.__module__ = __name__
