"""Streamed campaigns: features kept in place of the logs, identical to the logs' own features
(a dropped log's, computed without its Parquet bytes, too), for any number of workers and on a
Dask cluster, resumable after an interruption."""

from __future__ import annotations

import json
import os
import shutil
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from server.campaigns import (
    FEATURE_CACHE,
    LEGACY_DIGESTS,
    CampaignError,
    FeatureSink,
    checked_log,
    decode_log,
    load_campaign,
)
from server.feature_canary import canary_digest
from server.flightlog import write_parquet
from server.phm.features import FeatureConfig
from server.phm.recording import log_features
from server.phm.signal_quality import QualityConfig
from sim_worker.campaign import SCALES, ScaleConfig, run_campaign
from sim_worker.campaign.planning import execution_order, plan_campaign
from sim_worker.faults import THRESHOLDS, FaultState, healthy
from sim_worker.fleet import WingletMode, build_aircraft
from sim_worker.flight import flight_start, simulate_flight

#: one pattern per mode, every flight, short recordings and fast faults: seconds per campaign
TINY = ScaleConfig(duration_s=14.0, healthy_patterns=2, healthy_flights=3, patterns_per_mode=1,
                   render_every=1, apriori_flights=3, apriori_onset=1, lead_flights=2,
                   span_flights=(6.0, 10.0))


@pytest.fixture(scope="module", autouse=True)
def _tiny_scale():  # type: ignore[no-untyped-def]
    with pytest.MonkeyPatch.context() as mp:
        mp.setitem(SCALES, "tiny", {"design": TINY, "verification": TINY})
        yield


def _stream(out: Path, **kw: object) -> dict:
    """The tiny verification campaign, streamed (``sink=None``: every flight a file)."""
    kw.setdefault("sink", FeatureSink(keep_raw_every=4))
    return run_campaign("verification", out, seed=3, scale="tiny", progress=False, **kw)


def _files(out: Path) -> dict[str, bytes]:
    return {p.relative_to(out).as_posix(): p.read_bytes()
            for p in sorted(out.rglob("*")) if p.is_file()}


@pytest.fixture(scope="module")
def reference(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The tiny campaign streamed in this process, read only by the tests."""
    out = tmp_path_factory.mktemp("reference")
    _stream(out, workers=1)
    return out


def test_streamed_features_equal_the_features_of_the_written_log(reference: Path) -> None:
    tmp_path = reference
    manifest = json.loads((tmp_path / "manifest.json").read_text())
    stored = json.loads((tmp_path / FEATURE_CACHE).read_text())["flights"]
    flights = [f for p in manifest["patterns"] for f in p["flights"]]
    assert len(stored) == len(flights) > 30
    kept = [f for f in flights if f["file"]]
    # every 4th flight of a pattern keeps its log, the others only their features
    assert {f["index"] % 4 for f in kept} == {0}
    assert len(kept) == sum(1 for f in flights if f["index"] % 4 == 0)
    assert not list(tmp_path.rglob("*.tmp")) and not (tmp_path / "progress").exists()
    for f in kept:
        log = decode_log((tmp_path / f["file"]).read_bytes(), f["file"])
        from_file = log_features(log, config=FeatureConfig(), ground_temp_c=f["ground_temp_c"])
        # compared as JSON text: a feature without valid samples is NaN, and NaN != NaN
        assert json.dumps(from_file.to_dict()) == json.dumps(stored[f["flight"]])
    # the campaign reads back from the stored features alone, files or not
    campaign = load_campaign(tmp_path)
    assert sum(len(p.flights) for p in campaign.patterns) == len(flights)
    assert all(r.started_at is not None for p in campaign.patterns for r in p.flights)
    fault_runs = [p for p in manifest["patterns"] if p["failure_flight"] is not None]
    for p in fault_runs:  # every flight from onset to failure is rendered
        assert [f["index"] for f in p["flights"]] == list(range(p["failure_flight"] + 1))


@pytest.mark.parametrize(("mode", "position", "winglet"), [
    ("healthy", None, WingletMode.ACTIVE_STANDBY),
    ("TTS", "WL1", WingletMode.ACTIVE_STANDBY),
    ("BDO", "WT", WingletMode.ACTIVE_STANDBY),
    ("REWEAR", "WL2", WingletMode.ACTIVE_STANDBY),
    ("MTWEAR", "WL1", WingletMode.ACTIVE_ACTIVE),
])
def test_a_dropped_flight_is_analysed_as_its_written_log_would_be(
        mode: str, position: str | None, winglet: WingletMode, tmp_path: Path) -> None:
    fault = healthy() if mode == "healthy" else FaultState(mode, position, 0.7 * THRESHOLDS[mode],
                                                           THRESHOLDS[mode])
    log, summary = simulate_flight(build_aircraft("I-DROP01", "Turin", seed=5), fault, 3,
                                   np.random.default_rng(11), flight_id="I-DROP01-F00003",
                                   started_at=flight_start(3), duration_s=TINY.duration_s,
                                   winglet_mode=winglet)
    read = decode_log(write_parquet(log), "file")
    kept = checked_log(log, "memory")
    assert kept.metadata == read.metadata
    assert list(kept.channels) == list(read.channels)
    for name, values in read.channels.items():  # the same values to the bit
        assert kept.channels[name].dtype == values.dtype
        assert kept.channels[name].tobytes() == values.tobytes(), name
    sink = FeatureSink(keep_raw_every=2)
    dropped_rel, dropped = sink(tmp_path, "f/dropped.parquet", 1, log, summary.ground_temp_c)
    kept_rel, written = sink(tmp_path, "f/kept.parquet", 2, log, summary.ground_temp_c)
    assert dropped_rel is None and not (tmp_path / "f" / "dropped.parquet").exists()
    assert kept_rel == "f/kept.parquet"
    from_file = log_features(decode_log((tmp_path / kept_rel).read_bytes(), kept_rel),
                             config=FeatureConfig(),
                             ground_temp_c=summary.ground_temp_c).to_dict()
    # compared as JSON text: a feature without valid samples is NaN, and NaN != NaN
    assert json.dumps(dropped) == json.dumps(written) == json.dumps(from_file)


def test_stale_features_without_logs_are_refused(reference: Path) -> None:
    with pytest.raises(CampaignError, match="streamed without their logs"):
        load_campaign(reference, config=FeatureConfig(min_events=4))


def _as_legacy(reference: Path, out: Path, version: str) -> Path:
    """The reference campaign with its features cached as a version string keyed them."""
    shutil.copytree(reference, out)
    doc = json.loads((out / FEATURE_CACHE).read_text())
    doc["format"] = "phm-features/2"
    doc["config"] = f"{version} {FeatureConfig()!r} {QualityConfig()!r}"
    (out / FEATURE_CACHE).write_text(json.dumps(doc))
    return out


def test_a_campaign_cached_under_a_version_is_read_while_its_features_hold(
        reference: Path, tmp_path: Path) -> None:
    """A campaign cached before the canaries is read while today's features give the digest
    pinned for its version, and refused (its dropped flights have no features) otherwise."""
    flights = sum(len(p.flights) for p in load_campaign(reference).patterns)
    for version, pinned in LEGACY_DIGESTS.items():
        legacy = _as_legacy(reference, tmp_path / version.replace("/", "-"), version)
        if canary_digest() == pinned:
            assert sum(len(p.flights) for p in load_campaign(legacy).patterns) == flights
        else:
            with pytest.raises(CampaignError, match="streamed without their logs"):
                load_campaign(legacy)
    unknown = _as_legacy(reference, tmp_path / "unknown", "features/9")
    with pytest.raises(CampaignError, match="streamed without their logs"):
        load_campaign(unknown)


@pytest.mark.slow
def test_output_does_not_depend_on_the_number_of_workers(reference: Path,
                                                         tmp_path: Path) -> None:
    _stream(tmp_path / "two", workers=2)
    assert _files(reference) == _files(tmp_path / "two")


@pytest.mark.slow
def test_dask_cluster_gives_the_same_bytes(reference: Path, tmp_path: Path) -> None:
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        _stream(tmp_path / "dask", executor=client.get_executor())
    assert _files(reference) == _files(tmp_path / "dask")


_SIMULATED: list[str] = []


@dataclass(frozen=True)
class _CountingSink(FeatureSink):
    """Records every flight it is given; fails on the flights of one pattern."""

    fail_on: str | None = None

    def __call__(self, out_dir, rel, index, log, ground_temp_c):  # type: ignore[no-untyped-def]
        _SIMULATED.append(log.metadata.flight)
        if self.fail_on and log.metadata.flight.startswith(self.fail_on):
            raise RuntimeError("interrupted")
        return super().__call__(out_dir, rel, index, log, ground_temp_c)

    def describe(self):  # type: ignore[no-untyped-def]
        return FeatureSink.describe(self)  # the same campaign, whatever the test does


@pytest.mark.slow
def test_an_interrupted_campaign_resumes_without_simulating_finished_patterns(
        reference: Path, tmp_path: Path) -> None:
    _SIMULATED.clear()
    # patterns run in lockstep, the last in execution order once a lane is free: some have
    # finished, and are saved, before its first flight
    last = execution_order(plan_campaign("verification", 3, "tiny"))[-1].id
    with pytest.raises(RuntimeError, match="interrupted"):
        _stream(tmp_path / "cut", workers=1, sink=_CountingSink(keep_raw_every=4,
                                                                 fail_on=f"{last}-"))
    saved = {json.loads(p.read_text())["entry"]["id"]
             for p in (tmp_path / "cut" / "progress").glob("[0-9]*.json")}
    assert saved and not (tmp_path / "cut" / "manifest.json").exists()
    _SIMULATED.clear()
    _stream(tmp_path / "cut", workers=1, sink=_CountingSink(keep_raw_every=4))
    resumed = {f.rsplit("-", 1)[0] for f in _SIMULATED}
    assert resumed and not resumed & saved
    assert _files(reference) == _files(tmp_path / "cut")
    # a finished campaign is not simulated again, and other settings are refused
    _SIMULATED.clear()
    _stream(tmp_path / "cut", workers=1, sink=_CountingSink(keep_raw_every=4))
    assert _SIMULATED == []
    with pytest.raises(ValueError, match="other settings"):
        _stream(tmp_path / "cut", workers=1, sink=FeatureSink(keep_raw_every=5))


@pytest.mark.slow
def test_span_range_sets_the_fault_to_failure_spans(tmp_path: Path) -> None:
    fast = run_campaign("verification", tmp_path / "fast", seed=3, scale="tiny",
                        progress=False, workers=1, sink=FeatureSink(keep_raw_every=1000))
    slow = run_campaign("verification", tmp_path / "slow", seed=3, scale="tiny",
                        progress=False, workers=1, span_flights=(30.0, 40.0),
                        sink=FeatureSink(keep_raw_every=1000))
    assert slow["span_flights"] == [30.0, 40.0]

    def spans(m: dict) -> list[int]:
        return [p["failure_flight"] - p["onset_flight"] for p in m["patterns"]
                if p["failure_flight"] is not None]

    assert max(spans(fast)) < min(spans(slow))
    with pytest.raises(ValueError, match="span range"):
        run_campaign("verification", tmp_path / "bad", seed=3, scale="tiny", progress=False,
                     span_flights=(50.0, 20.0))


@pytest.mark.slow
def test_the_dask_option_of_the_command_line_uses_the_scheduler_given(tmp_path: Path) -> None:
    distributed = pytest.importorskip("distributed")
    from sim_worker.cli import main

    _stream(tmp_path / "local", workers=1, sink=None)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster:
        code = main(["campaign", "--kind", "verification", "--seed", "3", "--scale", "tiny",
                     "--out", str(tmp_path / "dask"), "--dask", cluster.scheduler_address,
                     "--no-progress"])
        # every pattern ran on the cluster's workers, none in this process: in groups, one
        # per worker of this machine's count when there are fewer patterns than 16 a worker
        n = len(json.loads((tmp_path / "dask" / "manifest.json").read_text())["patterns"])
        size = min(16, -(-n // (os.cpu_count() or 1)))
        tasks = cluster.scheduler.task_prefixes.get("run_patterns")
        assert tasks is not None and tasks.state_counts["memory"] == -(-n // size)
    assert code == 0
    assert _files(tmp_path / "local") == _files(tmp_path / "dask")
