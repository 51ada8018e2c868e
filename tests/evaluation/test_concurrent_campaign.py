"""A concurrent-fault campaign at the ci scale, streamed end to end as ``hmsm campaign`` streams
one (features kept, logs sampled): each flight's truth per fault in its manifest, readable by
the campaign reader, refused by training and the single-fault scoring, scored per fault by
the concurrent evaluation (``hmsm evaluate`` chooses it)."""

from __future__ import annotations

from pathlib import Path
from typing import Any, cast

import pytest

from server.campaigns import (
    CampaignError,
    FeatureSink,
    load_campaign,
    train_from_directory,
)
from server.phm.chain import PhmModel
from sim_worker.campaign import COMBINATIONS, run_campaign
from sim_worker.cli import main as sim_worker_main

FAULT_TRUTH = {"mode", "position", "severity", "severity_norm", "true_rul_flights",
               "failure_flight"}


@pytest.fixture(scope="module")
def campaign(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, Any]]:
    out = tmp_path_factory.mktemp("concurrent_ci")
    manifest = run_campaign("concurrent", out, seed=0, scale="ci", workers=1, progress=False,
                            per_mode=1, sink=FeatureSink(keep_raw_every=5))
    return out, manifest


def test_every_combination_flies_with_its_truth_per_fault(
        campaign: tuple[Path, dict[str, Any]]) -> None:
    _, manifest = campaign
    assert manifest["kind"] == "concurrent" and manifest["render_every"] == 1
    assert [p["mode"] for p in manifest["patterns"]] == [c.name for c in COMBINATIONS]
    for pattern in manifest["patterns"]:
        faults = pattern["faults"]
        assert len(faults) == 2 and all(f["started"] for f in faults)
        assert {f["outcome"] for f in faults} <= {"failed", "censored"}
        assert any(f["outcome"] == "failed" for f in faults)
        indices = [fl["index"] for fl in pattern["flights"]]
        assert indices == list(range(len(indices)))  # every flight rendered
        assert indices[-1] == max(f["end_flight"] for f in faults)
        for fl in pattern["flights"]:
            assert "severity" not in fl and "true_rul_flights" not in fl
            for truth in fl["faults"]:
                assert set(truth) == FAULT_TRUTH
                planned = next(f for f in faults if (f["mode"], f["position"]) ==
                               (truth["mode"], truth["position"]))
                assert planned["onset_flight"] <= fl["index"] <= planned["end_flight"]
                assert truth["failure_flight"] == planned["failure_flight"]
                if planned["failure_flight"] is not None:
                    assert truth["true_rul_flights"] == planned["failure_flight"] - fl["index"]
                else:
                    assert truth["true_rul_flights"] is None
        onsets = sorted(f["onset_flight"] for f in faults)
        assert onsets[0] == manifest["lead_flights"] < onsets[1]
    assert any(f["outcome"] == "censored" for p in manifest["patterns"] for f in p["faults"])


def test_the_reader_loads_it_and_training_and_the_single_fault_scoring_refuse_it(
        campaign: tuple[Path, dict[str, Any]]) -> None:
    out, manifest = campaign
    loaded = load_campaign(out)
    assert loaded.kind == "concurrent"
    assert sum(len(p.flights) for p in loaded.patterns) == sum(
        len(p["flights"]) for p in manifest["patterns"])
    from server.evaluation import evaluate_campaign

    with pytest.raises(CampaignError, match="concurrent-fault campaign.*hmsm evaluate scores"):
        evaluate_campaign(cast(PhmModel, None), out)
    with pytest.raises(CampaignError, match="training reads single-fault campaigns"):
        train_from_directory(out)


def test_hmsm_evaluate_scores_it_per_fault(campaign: tuple[Path, dict[str, Any]],
                                           tmp_path: Path) -> None:
    """The whole command on the streamed campaign with the shipped model: a fact per fault of
    every pattern, the table per combination kind, the dashboard's latest.json left alone."""
    import json

    from server.cli import main as hmsm_main

    out, manifest = campaign
    assert hmsm_main(["evaluate", "--campaign", str(out), "--model-json",
                      "server/data/demo_model.json", "--out", str(tmp_path / "ev"),
                      "--no-progress", "--jobs", "1"]) == 0
    result = json.loads((tmp_path / "ev" / "concurrent.json").read_text())
    rows = result["summary"]["patterns"]
    assert [r["id"] for r in rows] == [p["id"] for p in manifest["patterns"]]
    for row, pattern in zip(rows, manifest["patterns"], strict=True):
        assert [(f["mode"], f["position"]) for f in row["faults"]] == [
            (f["mode"], f["position"]) for f in pattern["faults"]]
        for f in row["faults"]:
            assert f["alarmed"] is None or f["onset"] <= f["alarmed"] <= f["end"]
    table = (tmp_path / "ev" / "concurrent.md").read_text()
    assert all(f"| {c.name} |" in table for c in COMBINATIONS) and "| all | 5 |" in table
    assert not (tmp_path / "ev" / "evaluation.json").exists()


def test_the_cli_refuses_a_scale_without_concurrent_patterns(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``sim-worker campaign --kind concurrent`` at a scale without concurrent patterns is
    refused before any simulation."""
    out = tmp_path
    assert sim_worker_main(["campaign", "--kind", "concurrent", "--out", str(out / "x"),
                            "--scale", "paper", "--no-progress"]) == 2
    assert "the paper scale has no concurrent campaign" in capsys.readouterr().err
    assert not (out / "x" / "manifest.json").exists()
    from sim_worker.cli import build_parser

    args = build_parser().parse_args(["campaign", "--kind", "concurrent", "--out", "d",
                                      "--scale", "ci", "--per-mode", "1"])
    assert (args.kind, args.per_mode) == ("concurrent", 1)


def test_a_mode_beyond_the_leaders_cross_talk_is_named_beside_it(
        campaign: tuple[Path, dict[str, Any]]) -> None:
    """The chain names a progressive mode whose pooled own feature is beyond the leading
    mode's limit: with every limit at -inf every progressive mode joins a progressive leader;
    at +inf the set is the own probabilities' alone; the traces keep the pooled features."""
    import math
    from dataclasses import replace

    from server.demo_model import load_demo_model
    from server.evaluation.concurrent import run_concurrent_pattern
    from server.phm.chain import read_model_document
    from server.phm.classification.crosstalk import CrossTalk, CrossTalkLimit
    from server.phm.classification.modes import modes_present
    from server.vocabulary import PROGRESSIVE

    out, _ = campaign
    model = read_model_document(load_demo_model()["payload"])
    pattern = load_campaign(out).patterns[0]

    def limits(value: float) -> CrossTalk:
        return CrossTalk(0.99, {lead: {m: CrossTalkLimit(value) for m in PROGRESSIVE
                                       if m != lead} for lead in PROGRESSIVE})

    wide = run_concurrent_pattern(replace(model, crosstalk=limits(-math.inf)), pattern)
    shut = run_concurrent_pattern(replace(model, crosstalk=limits(math.inf)), pattern)
    led = 0
    for fw, fs in zip(wide["flights"], shut["flights"], strict=True):
        for pos, unit in fs["units"].items():
            if not unit.get("own") or unit["fault_mode"] not in PROGRESSIVE:
                continue
            led += 1
            assert set(unit["own_features"]) >= set(PROGRESSIVE)
            assert unit["modes"] == modes_present(unit["fault_mode"], unit["own"])
            assert set(fw["units"][pos]["modes"]) >= set(PROGRESSIVE)
    assert led > 0
