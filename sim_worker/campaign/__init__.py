"""Campaigns: design / verification / concurrent-fault sets of flight logs plus a manifest with
the ground truth.

Layout: ``DIR/manifest.json`` and ``DIR/flights/<tail>/<flight>.parquet``; DIR a local
directory or an S3 prefix ``s3://bucket/prefix`` (``server.campaign_store.CampaignStore``),
which the workers write kept logs to directly: a Dask cluster needs no shared filesystem. The
manifest schema (``ema-campaign/1``) is a contract with the PHM chain; see :func:`run_campaign`.
What becomes of a rendered flight is the campaign's :class:`FlightSink`'s choice: its file
(:class:`ParquetSink`, the default) or, streamed, its features (``server.campaigns.FeatureSink``).

Determinism: every aircraft seed, pattern seed and flight seed derives from the campaign seed via
``numpy.random.SeedSequence`` with a fixed key (kind, aircraft, pattern, flight), never from the
worker that runs it; results are identical for any number of workers or any executor.
Resumable: finished patterns are kept in ``DIR/progress/`` until the manifest is written.

The package, one job a module (the names other code uses are re-exported here):

* :mod:`.scales`: what each scale flies (:class:`ScaleConfig`, :data:`SCALES`), the test
  station's envelope and the design's sensor study;
* :mod:`.sensor_faults`: sensor-fault specs (:class:`SensorFault`) and the aircraft they give;
* :mod:`.planning`: the fleet, the patterns and their order, each flight's seed, recording
  length and conditions;
* :mod:`.pattern`: running one pattern (fault-to-failure runs, the sinks of rendered flights);
* :mod:`.concurrent`: a concurrent pattern's run (two faults at once) and its truth per fault;
* :mod:`.run`: running a campaign (pool or executor, resuming, settings, manifest, snapshot).
"""

from __future__ import annotations

from .pattern import FlightSink, ParquetSink, PatternTask, run_pattern
from .planning import (
    COMBINATIONS,
    KINDS,
    PatternSpec,
    block_conditions,
    execution_order,
    fleet_for,
    plan_campaign,
    recording_s,
)
from .run import FORMAT, SETTINGS_FILE, run_campaign, snapshot_campaign
from .scales import (
    SCALES,
    SENSOR_STUDY_FLIGHTS,
    SENSOR_STUDY_NOISE,
    SENSOR_STUDY_PATTERNS,
    STATION_ENVELOPE,
    ScaleConfig,
)
from .sensor_faults import SensorFault

__all__ = ["ScaleConfig", "SCALES", "plan_campaign", "execution_order", "run_campaign",
           "snapshot_campaign", "run_pattern", "FORMAT",
           "SETTINGS_FILE", "FlightSink", "ParquetSink", "PatternTask", "SensorFault",
           "fleet_for", "PatternSpec", "STATION_ENVELOPE", "SENSOR_STUDY_PATTERNS",
           "SENSOR_STUDY_NOISE", "SENSOR_STUDY_FLIGHTS", "block_conditions", "recording_s",
           "KINDS", "COMBINATIONS"]
