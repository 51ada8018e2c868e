"""The paper's protocol end to end, reduced (``hmsm protocol --scale ci``): two streamed
campaigns, every flight of every pattern, training, evaluation with intervals. A regression
test of the machinery; its figures are not the system's (a few patterns, short recordings)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from server.vocabulary import PROGRESSIVE

pytestmark = pytest.mark.slow

KEEP = 10


@pytest.fixture(scope="module")
def protocol_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("protocol")
    proc = subprocess.run(
        [sys.executable, "-m", "server.cli", "protocol", "--scale", "ci", "--out", str(out),
         "--workers", "2", "--keep-raw-every", str(KEEP), "--no-progress"],
        capture_output=True, text=True, timeout=1200,
        env={**os.environ, "HMSM_DATA_DIR": str(out / "data")})
    assert proc.returncode == 0, proc.stderr[-3000:]
    return out


def _manifest(root: Path, kind: str) -> dict:
    return json.loads((root / kind / "manifest.json").read_text())


@pytest.mark.parametrize("kind", ["design", "verification"])
def test_every_flight_is_streamed_and_a_sample_kept(protocol_run: Path, kind: str) -> None:
    manifest = _manifest(protocol_run, kind)
    assert manifest["render_every"] == 1 and manifest["sink"]["sink"] == "features"
    stored = json.loads((protocol_run / kind / "phm_features.json").read_text())["flights"]
    flights = [f for p in manifest["patterns"] for f in p["flights"]]
    assert set(stored) == {f["flight"] for f in flights}
    for f in flights:
        assert bool(f["file"]) == (f["index"] % KEEP == 0)
        if f["file"]:
            assert (protocol_run / kind / f["file"]).is_file()
    for p in manifest["patterns"]:
        if p["mode"] in PROGRESSIVE:
            assert [f["index"] for f in p["flights"]] == list(range(p["failure_flight"] + 1))
    assert not (protocol_run / kind / "progress").exists()


def test_the_model_is_on_disk_before_the_verification_streams(protocol_run: Path) -> None:
    """A run stopped during the verification's hours keeps the model of its finished design
    (`hmsm protocol --model-json OUT/model.json` scores the verification alone)."""
    logs = list((protocol_run / "verification" / "flights").rglob("*.parquet"))
    assert logs
    first_log = min(f.stat().st_mtime for f in logs)
    assert (protocol_run / "model.json").stat().st_mtime < first_log


def test_every_verification_flight_is_analysed_and_scored_with_intervals(
        protocol_run: Path) -> None:
    manifest = _manifest(protocol_run, "verification")
    result = json.loads((protocol_run / "evaluation" / "evaluation.json").read_text())
    assert sum(len(p["flights"]) for p in result["patterns"]) == \
        sum(len(p["flights"]) for p in manifest["patterns"])
    summary = json.loads((protocol_run / "evaluation" / "summary.json").read_text())
    healthy = sum(len(p["flights"]) for p in manifest["patterns"] if p["mode"] == "healthy")
    onsets = sum(p["onset_flight"] for p in manifest["patterns"] if p["mode"] != "healthy")
    assert summary["detection"]["false_alarms"]["healthy_flights"] == healthy + onsets
    assert set(summary["prognosis"]) == set(PROGRESSIVE)
    for mode, figures in summary["prognosis"].items():
        assert figures["n_patterns"] == 2, mode
        for key in ("ph", "ph_cone", "ra", "alpha_lambda"):
            lo, hi = figures[f"{key}_ci"]
            assert lo <= figures[key] <= hi, (mode, key)
        cal = figures["calibration"]
        assert cal["n_predictions"] > 0 and 0.0 <= cal["central_50"] <= cal["central_90"] <= 1.0
    assert len((protocol_run / "evaluation" / "summary.json").read_bytes()) < 60_000


def test_the_verification_rate_is_set_beside_the_design_measured_one(protocol_run: Path) -> None:
    """The false-alarm rate per unit-flight stands beside the rate the trained model's design
    measured over its own healthy lives, with whether it falls inside that interval."""
    model = json.loads((protocol_run / "model.json").read_text())
    design = model["training"]["detector"]["design_false_alarms"]
    summary = json.loads((protocol_run / "evaluation" / "summary.json").read_text())
    pu = summary["detection"]["per_unit_flight"]
    assert pu["design_measured"]["unit_flights"] == design["unit_flights"] > 0
    assert pu["design_measured"]["interval"] == design["interval"]
    lo, hi = design["interval"]
    assert pu["within_design_interval"] is (lo <= pu["rate"] <= hi)


def test_a_finished_campaign_is_never_overwritten(protocol_run: Path) -> None:
    before = (protocol_run / "verification" / "phm_features.json").read_bytes()
    proc = subprocess.run(
        [sys.executable, "-c",
         "import sys; from sim_worker.cli import main; sys.exit(main(sys.argv[1:]))",
         "campaign", "--kind", "verification", "--scale", "ci", "--seed", "2",
         "--out", str(protocol_run / "verification"), "--no-progress"],
        capture_output=True, text=True, timeout=120)
    # the raw-log runner is another sink: the finished streamed campaign is not overwritten
    assert proc.returncode == 2 and "other settings" in proc.stderr
    assert (protocol_run / "verification" / "phm_features.json").read_bytes() == before


def _interrupted_verification(out: Path, patterns: int) -> list[str]:
    """The ci verification campaign as a run stopped after its first ``patterns`` patterns
    (in the order a run simulates them) leaves it: their results in ``out/progress``."""
    from server.campaigns import FeatureSink
    from sim_worker.campaign import (
        SCALES,
        PatternTask,
        execution_order,
        plan_campaign,
        run_pattern,
    )
    from sim_worker.campaign.run import _Progress, _settings

    cfg, sink = SCALES["ci"]["verification"], FeatureSink(keep_raw_every=KEEP)
    options = {"bases": None, "noise_scale": 1.0, "sensor_faults": ()}
    store = _Progress(out, _settings("verification", 2, "ci", cfg, options, sink))
    first = execution_order(plan_campaign("verification", 2, "ci"))[:patterns]
    for spec in first:
        store.save(spec, run_pattern(PatternTask(str(out), "verification", 2, cfg, spec,
                                                 options, sink)))
    return [s.id for s in first]


def test_a_running_verification_is_scored_on_the_patterns_it_has_finished(
        protocol_run: Path, tmp_path: Path) -> None:
    """``hmsm protocol --score-finished`` copies out the finished patterns of a verification
    still running, exactly as the whole run writes them, and scores them; the run's own
    progress is left as it was. A run's first round holds one pattern of every mode."""
    root = tmp_path / "run"
    (root / "design").parent.mkdir(parents=True)
    (root / "design").symlink_to(protocol_run / "design", target_is_directory=True)
    ids = _interrupted_verification(root / "verification", 8)
    assert sorted(i.split("-")[1] for i in ids) == sorted(
        ["TTS", "DMD", "MTEL", "MTWEAR", "REWEAR", "healthy", "SE", "BDO"])
    progress = sorted(p.name for p in (root / "verification" / "progress").iterdir())
    proc = subprocess.run(
        [sys.executable, "-m", "server.cli", "protocol", "--scale", "ci", "--out", str(root),
         "--workers", "2", "--keep-raw-every", str(KEEP), "--no-progress", "--score-finished"],
        capture_output=True, text=True, timeout=600,
        env={**os.environ, "HMSM_DATA_DIR": str(tmp_path / "data")})
    assert proc.returncode == 0, proc.stderr[-3000:]
    full = _manifest(protocol_run, "verification")
    assert f"scoring 8 of {len(full['patterns'])} verification patterns" in proc.stdout
    assert sorted(p.name for p in (root / "verification" / "progress").iterdir()) == progress
    part = json.loads((root / "partial" / "verification" / "manifest.json").read_text())
    assert part["partial"] == {"patterns": 8, "of": len(full["patterns"])}
    assert part["patterns"] == [p for p in full["patterns"] if p["id"] in ids]
    stored = json.loads((root / "partial" / "verification" / "phm_features.json").read_text())
    whole = json.loads((protocol_run / "verification" / "phm_features.json").read_text())
    assert stored["flights"] == {f: v for f, v in whole["flights"].items() if f in
                                 stored["flights"]}
    summary = json.loads((root / "partial" / "evaluation" / "summary.json").read_text())
    assert summary["campaign"]["patterns"] == 8
    assert summary["campaign"]["partial"] == part["partial"]
    assert {m: f["n_patterns"] for m, f in summary["prognosis"].items()} == \
        {m: 1 for m in PROGRESSIVE}


def test_scoring_a_part_needs_a_complete_design(tmp_path: Path) -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "server.cli", "protocol", "--scale", "ci", "--out",
         str(tmp_path), "--no-progress", "--score-finished"],
        capture_output=True, text=True, timeout=120,
        env={**os.environ, "HMSM_DATA_DIR": str(tmp_path / "data")})
    assert proc.returncode == 2 and "design campaign is not complete" in proc.stderr


def test_the_trained_model_is_kept_and_scores_the_verification_alone(
        protocol_run: Path, tmp_path: Path) -> None:
    """The run keeps the model it trained (``OUT/model.json``, with where it was trained and
    its training report); ``--model-json`` with it scores a verification without any design
    campaign, to the same figures as the whole run."""
    from server.evaluation.protocol import MODEL_FORMAT

    doc = json.loads((protocol_run / "model.json").read_text())
    assert doc["format"] == MODEL_FORMAT
    assert doc["design"] == {"kind": "design", "scale": "ci", "seed": 1}
    assert doc["payload"]["format"].startswith("ema-phm-model/")
    assert "timings_s" not in json.dumps(doc["training"])
    root = tmp_path / "run"
    root.mkdir()
    (root / "verification").symlink_to(protocol_run / "verification", target_is_directory=True)
    proc = subprocess.run(
        [sys.executable, "-m", "server.cli", "protocol", "--scale", "ci", "--out", str(root),
         "--workers", "2", "--keep-raw-every", str(KEEP), "--no-progress",
         "--model-json", str(protocol_run / "model.json")],
        capture_output=True, text=True, timeout=600,
        env={**os.environ, "HMSM_DATA_DIR": str(tmp_path / "data")})
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert not (root / "design").exists() and not (root / "model.json").exists()
    whole = json.loads((protocol_run / "evaluation" / "summary.json").read_text())
    alone = json.loads((root / "evaluation" / "summary.json").read_text())
    for key in ("prognosis", "detection", "classification"):
        assert alone[key] == whole[key], key
    assert alone["model"]["sha256"] == whole["model"]["sha256"]
    assert alone["model"]["classifier_accuracy"] == whole["model"]["classifier_accuracy"]
