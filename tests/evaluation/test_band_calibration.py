"""``hmsm calibrate``: the bands' layer fitted on replays, written into the model document."""

from __future__ import annotations

import copy
import json
import math

import numpy as np

from server.cli import main
from server.demo_model import load_demo_model
from server.phm.chain import read_model_document


def _trace(rng: np.random.Generator, mode: str, life: int, bias: float) -> dict:
    """A replayed run: alarm at flight 10, failure at 10 + life, bands 5-95 % of sd 0.2 in
    log around a median off the truth by ``bias`` (too narrow and biased: to be widened)."""
    flights = []
    for k in range(life + 12):
        true = 10 + life - k
        doc = None
        if 10 <= k < 10 + life:
            med = true * math.exp(bias + 0.3 * rng.standard_normal())
            doc = {"quantiles": [[lv, med * math.exp(0.2 * z)] for lv, z in
                                 ((0.05, -1.645), (0.25, -0.674), (0.5, 0.0), (0.75, 0.674),
                                  (0.95, 1.645))], "rate_ratio": 3.0}
        flights.append({"index": k, "alarm": k >= 10, "true_rul": float(max(true, 0)),
                        "fault_mode": mode if k >= 10 else None, "rul": doc})
    return {"mode": mode, "onset": 2, "failure": 10 + life, "flights": flights}


def _uncalibrated() -> dict:
    """The shipped model without the layers it ships with."""
    doc = load_demo_model()
    for spec in doc["payload"]["measurement"].values():
        spec.pop("band_calibration", None)
    return doc


def _evaluation(tmp_path, traces, seed=3):
    path = tmp_path / f"eval_{seed}"
    path.mkdir()
    (path / "evaluation.json").write_text(json.dumps(
        {"campaign": {"kind": "design", "seed": seed}, "patterns": traces}))
    return path


def test_calibrate_writes_each_modes_layer_and_the_chain_reads_it(tmp_path, capsys):
    rng = np.random.default_rng(0)
    traces = [_trace(rng, "DMD", int(rng.integers(30, 300)), 0.5) for _ in range(8)]
    model = tmp_path / "model.json"
    model.write_text(json.dumps(_uncalibrated()))
    out = tmp_path / "calibrated.json"
    assert main(["calibrate", "--evaluation", str(_evaluation(tmp_path, traces)),
                 "--model-json", str(model), "--out", str(out)]) == 0
    chain = read_model_document(json.loads(out.read_text()))
    layer = chain.measurement["DMD"].band_calibration
    assert layer is not None and layer.n_records == 8 * 20 and layer.n_runs == 8
    # the replays' 90 % bands were optimistic (the truth below them): their lower ends move
    # down, their upper ends in
    lower, upper = layer.margins_for(3.0)[1][0.9]
    assert lower > 0.3 and upper < 0.0
    assert chain.measurement["TTS"].band_calibration is None  # no replay of TTS
    assert "DMD: 160 records from 8 runs" in capsys.readouterr().out


def test_calibrate_refuses_the_models_own_design_and_calibrated_replays(tmp_path, capsys):
    rng = np.random.default_rng(1)
    traces = [_trace(rng, "MTEL", 80, 0.0) for _ in range(4)]
    doc = _uncalibrated()
    model = tmp_path / "model.json"
    model.write_text(json.dumps(doc))
    own = _evaluation(tmp_path, traces, seed=doc["design"]["seed"])
    assert main(["calibrate", "--evaluation", str(own), "--model-json", str(model),
                 "--out", str(tmp_path / "x.json")]) != 0
    assert "own design campaign" in capsys.readouterr().err
    calibrated = copy.deepcopy(traces)
    for f in calibrated[0]["flights"]:
        if f["rul"]:
            f["rul"]["adjustment"] = {"conformal_margins": {}}
    assert main(["calibrate", "--evaluation", str(_evaluation(tmp_path, calibrated, seed=5)),
                 "--model-json", str(model), "--out", str(tmp_path / "y.json")]) != 0
    assert "calibrated model" in capsys.readouterr().err
    shipped = tmp_path / "shipped.json"  # a model that has its layers already
    shipped.write_text(json.dumps(load_demo_model()))
    assert main(["calibrate", "--evaluation", str(_evaluation(tmp_path, traces, seed=6)),
                 "--model-json", str(shipped), "--out", str(tmp_path / "z.json")]) != 0
    assert "already has a calibration layer" in capsys.readouterr().err
    assert not (tmp_path / "x.json").exists() and not (tmp_path / "y.json").exists()


def test_calibrate_splits_each_lead_by_its_weight_when_asked(tmp_path):
    """``--weight-split``: the replays' leads (here every other prediction ambiguous) are
    calibrated apart, and the chain reads the split layer back."""
    rng = np.random.default_rng(2)
    traces = [_trace(rng, "DMD", int(rng.integers(30, 300)), 0.5) for _ in range(8)]
    for trace in traces:
        for k, f in enumerate(trace["flights"]):
            if f["rul"]:
                f["rul"]["hypothesis"] = {"name": "fast", "weight": 0.6 if k % 2 else 0.95}
    model = tmp_path / "model.json"
    model.write_text(json.dumps(_uncalibrated()))
    out = tmp_path / "calibrated.json"
    args = ["calibrate", "--evaluation", str(_evaluation(tmp_path, traces)),
            "--model-json", str(model), "--out", str(out)]
    assert main([*args, "--weight-split", "1.5"]) != 0 and not out.exists()
    assert main([*args, "--weight-split", "0"]) == 0  # 0: no split
    layer = read_model_document(json.loads(out.read_text())).measurement["DMD"].band_calibration
    assert layer is not None and layer.weight_split is None and layer.split_counts == ()
    assert main(args) == 0  # the default splits at 0.8
    layer = read_model_document(json.loads(out.read_text())).measurement["DMD"].band_calibration
    assert layer is not None and layer.weight_split == 0.8
    ambiguous, confident = layer.split_counts[:2]  # the fast hypothesis's two halves
    assert ambiguous > 60 and confident > 60 and ambiguous + confident == 160
    assert sum(layer.split_counts[2:]) == 0
