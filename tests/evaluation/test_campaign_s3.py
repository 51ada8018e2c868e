"""Campaigns on an S3 object store (moto's server over HTTP): Dask workers that share no
directory write the kept logs there, the client the manifest, progress and features; the
campaign reads back from there, and an interrupted one resumes there."""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, replace
from pathlib import Path

import pytest

from server.campaign_store import CampaignStore
from server.campaigns import (
    FEATURE_CACHE,
    FeatureSink,
    decode_log,
    load_campaign,
    read_manifest,
    read_started_at,
)
from sim_worker.campaign import SCALES, plan_campaign, run_campaign, snapshot_campaign

MODEL = Path(__file__).resolve().parents[2] / "docs" / "results" / "protocol_model.json"
#: the ci scale (every flight, 30 s recordings) with two healthy patterns of six flights:
#: with --per-mode 0, twelve flights
SCALE = "ci-s3"


@pytest.fixture
def store_env(s3_server, monkeypatch: pytest.MonkeyPatch):  # type: ignore[no-untyped-def]
    """A bucket of its own, the endpoint where the service's setting names it, and the
    reduced ci scale."""
    monkeypatch.setenv("HMSM_S3_ENDPOINT_URL", s3_server.endpoint)
    monkeypatch.setitem(SCALES, SCALE, {k: replace(c, healthy_patterns=2)
                                        for k, c in SCALES["ci"].items()})
    return s3_server, s3_server.new_bucket()


def _empty_dirs(*dirs: Path) -> dict[str, list[str]]:
    """What was written below each directory (nothing, for a campaign on S3)."""
    return {str(d): sorted(str(p.relative_to(d)) for p in d.rglob("*")) for d in dirs}


@pytest.mark.slow
def test_a_dask_campaign_writes_to_s3_from_workers_that_share_no_directory(
        store_env, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    distributed = pytest.importorskip("distributed")
    from server.cli import main

    server, bucket = store_env
    client_dir, *worker_dirs = (tmp_path / name for name in ("client", "w1", "w2"))
    for d in (client_dir, *worker_dirs):
        d.mkdir()
    monkeypatch.chdir(client_dir)
    url = f"s3://{bucket}/campaigns/verification"
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None,
                                  local_directory=str(tmp_path / "dask")) as cluster, \
            distributed.Client(cluster) as client:
        workers = sorted(client.scheduler_info()["workers"])
        assert len(workers) == 2
        for addr, d in zip(workers, worker_dirs, strict=True):  # a working directory each
            client.run(os.chdir, str(d), workers=[addr])
        code = main(["campaign", "--kind", "verification", "--seed", "3", "--scale", SCALE,
                     "--per-mode", "0", "--keep-raw-every", "4", "--out", url,
                     "--dask", cluster.scheduler_address, "--no-progress"])
        # one task per worker: a group of patterns each (2 patterns, 2 workers)
        ran = cluster.scheduler.task_prefixes["run_patterns"].state_counts["memory"]
    assert code == 0
    assert _empty_dirs(client_dir, *worker_dirs) == {str(d): [] for d in
                                                     (client_dir, *worker_dirs)}
    manifest = read_manifest(url)
    flights = [f for p in manifest["patterns"] for f in p["flights"]]
    assert ran == len(manifest["patterns"]) == 2 and len(flights) == 12
    kept = sorted(f["file"] for f in flights if f["file"])
    assert len(kept) == 4  # flights 0 and 4 of each pattern
    keys = server.keys(bucket)
    assert {f"campaigns/verification/{k}" for k in
            ("manifest.json", FEATURE_CACHE, *kept)} <= set(keys)
    assert not [k for k in keys if "/progress/" in k or k.endswith(".tmp")]
    # read back: every flight's features, and a kept log as an upload is read
    campaign = load_campaign(url)
    assert sum(len(p.flights) for p in campaign.patterns) == 12
    stored = json.loads(CampaignStore.at(url, server.endpoint).read(FEATURE_CACHE))["flights"]
    log = decode_log(CampaignStore.at(url, server.endpoint).read(kept[0]), kept[0])
    assert log.metadata.flight in stored
    with CampaignStore.at(url, server.endpoint).open(kept[0]) as f:  # its footer alone
        assert read_started_at(f) == log.metadata.started_at
    # and is evaluated from there, feature timing included (it reads kept logs back)
    assert main(["evaluate", "--campaign", url, "--model-json", str(MODEL), "--jobs", "1",
                 "--timing-flights", "2", "--no-latest", "--no-progress",
                 "--out", str(tmp_path / "evaluation")]) == 0
    result = json.loads((tmp_path / "evaluation" / "evaluation.json").read_text())
    assert result["campaign"]["dir"] == url and result["campaign"]["flights"] == 12
    assert result["timing"]["features"]["flights"] == 2


@pytest.mark.slow
def test_a_design_campaign_on_s3_trains_a_model(store_env, tmp_path: Path) -> None:
    """The ci design (the least a model trains on), streamed to S3 by a local process pool
    (forked workers, each its own client) and trained on from there."""
    from server.cli import main
    from server.phm.chain import read_model_document

    _, bucket = store_env
    url, model = f"s3://{bucket}/design", tmp_path / "model.json"
    assert main(["campaign", "--kind", "design", "--seed", "1", "--scale", "ci", "--workers",
                 "2", "--keep-raw-every", "10", "--no-progress", "--out", url]) == 0
    assert main(["train", url, "--out", str(model)]) == 0
    doc = json.loads(model.read_text())
    read_model_document(doc)
    trained_on = [p for p in read_manifest(url)["patterns"] if not p.get("sensor_study")]
    assert doc["training"]["campaign"]["patterns"] == len(trained_on)


_SIMULATED: list[str] = []


@dataclass(frozen=True)
class _StoppingSink(FeatureSink):
    """Records every flight it is given; stops the run on the flights of one pattern."""

    stop_on: str | None = None

    def __call__(self, out, rel, index, log, ground_temp_c):  # type: ignore[no-untyped-def]
        _SIMULATED.append(log.metadata.flight)
        if self.stop_on and log.metadata.flight.startswith(self.stop_on):
            raise RuntimeError("interrupted")
        return super().__call__(out, rel, index, log, ground_temp_c)

    def describe(self):  # type: ignore[no-untyped-def]
        return FeatureSink.describe(self)  # the same campaign, whatever the test does


@pytest.mark.slow
def test_an_interrupted_campaign_on_s3_resumes_without_simulating_finished_patterns(
        store_env) -> None:
    server, bucket = store_env
    out = CampaignStore.at(f"s3://{bucket}/cut", server.endpoint)

    def run(stop_on: str | None = None) -> dict:
        return run_campaign("verification", out, seed=3, scale=SCALE, per_mode=0,
                            workers=1, progress=False,
                            sink=_StoppingSink(keep_raw_every=4, stop_on=stop_on))

    _SIMULATED.clear()
    # the two patterns fly in lockstep: stopped on the second's last flight, the first (its
    # last flight in the same round, before it) is finished and saved
    last = next(s.n_flights for s in plan_campaign("verification", 3, SCALE, per_mode=0)
                if s.id == "V-healthy-02") - 1
    with pytest.raises(RuntimeError, match="interrupted"):
        run(stop_on=f"V-healthy-02-{last:04d}")
    assert set(server.keys(bucket)) >= {"cut/progress/settings.json", "cut/progress/0000.json"}
    assert not out.exists("manifest.json")
    # the finished pattern scored while the run is stopped: its kept logs copied beside it
    snap = out.child("snap")
    part = snapshot_campaign(out, snap, sink=FeatureSink(keep_raw_every=4))
    assert part["partial"] == {"patterns": 1, "of": 2}
    kept = [f["file"] for p in part["patterns"] for f in p["flights"] if f["file"]]
    assert kept and all(snap.read(k) == out.read(k) for k in kept)
    assert [p.id for p in load_campaign(snap).patterns] == ["V-healthy-01"]
    _SIMULATED.clear()
    manifest = run()
    assert {f.rsplit("-", 1)[0] for f in _SIMULATED} == {"V-healthy-02"}
    assert [p["id"] for p in manifest["patterns"]] == ["V-healthy-01", "V-healthy-02"]
    assert not [k for k in server.keys(bucket) if k.startswith("cut/progress")]
    _SIMULATED.clear()
    assert run() == manifest and _SIMULATED == []  # finished: read back, nothing simulated


def test_a_malformed_s3_location_is_refused_before_any_simulation(capsys) -> None:
    from sim_worker.cli import main

    code = main(["campaign", "--kind", "design", "--out", "s3://No_Such/bucket"])
    assert code == 2
    assert "s3://bucket or s3://bucket/prefix" in capsys.readouterr().err


def test_a_missing_bucket_is_refused_before_any_simulation(store_env, capsys) -> None:
    from sim_worker.cli import main

    code = main(["campaign", "--kind", "design", "--out", "s3://no-such-bucket/camp"])
    assert code == 2
    assert "no bucket 'no-such-bucket'" in capsys.readouterr().err


def test_train_and_protocol_say_what_they_take(store_env, tmp_path: Path, capsys) -> None:
    from server.cli import main

    _, bucket = store_env
    assert main(["train", f"s3://{bucket}/nothing", "--out", str(tmp_path / "m.json")]) == 2
    assert f"s3://{bucket}/nothing has no manifest.json" in capsys.readouterr().err
    assert main(["protocol", "--out", f"s3://{bucket}/run", "--scale", "ci"]) == 2
    assert "takes a local directory" in capsys.readouterr().err
    assert not (tmp_path / "m.json").exists()
