"""``hmsm demo`` starts on the shipped model, which ``hmsm demo-model`` produces from the
shipped design campaign of seed 1 (its provenance is checked against today's code; with
``HMSM_SHIPPED_DESIGN`` set to a streamed copy of that campaign, a fresh training is compared
with it); the fleet and the injections are ready without any training, and the sim worker
flies on the uploader and operator keys given in its environment."""

from __future__ import annotations

import json
import math
import os
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient
from sqlalchemy import select

from server.app import create_app
from server.config import Settings
from server.db import make_engine, make_session_factory
from server.demo import DEMO_INJECTIONS, prepare_demo
from server.demo_model import (
    DESIGN_SCALE,
    DESIGN_SEED,
    TRAINING_SEED,
    check_design,
    design_record,
    load_demo_model,
    portable_report,
)
from server.errors import Unprocessable
from server.models import Aircraft, Injection, ModelVersion
from server.phm.chain import read_model_document
from server.phm.prognosis.calibration import DEFAULT_WEIGHT_SPLIT
from sim_worker.campaign import plan_campaign
from sim_worker.cli import build_parser
from sim_worker.service import Api, SimFleetRunner


def test_the_shipped_model_records_the_design_todays_code_describes() -> None:
    """The shipped model's design is today's ``shipped`` scale of seed 1 read with today's
    features: a change of the scale (healthy cycles, recordings, conditions) or of a feature
    fails here until ``hmsm demo-model`` (and ``hmsm calibrate``) are run again. Its training
    report saw every planned pattern, and its leave-one-aircraft-out healthy rate is stated
    with its exposure."""
    shipped = load_demo_model()
    assert shipped["design"] == design_record()
    assert shipped["training_seed"] == TRAINING_SEED
    planned = plan_campaign("design", DESIGN_SEED, DESIGN_SCALE)
    campaign = shipped["training"]["campaign"]
    # the sensor study's twins teach the sensor model, not the chain's patterns
    assert (campaign["kind"], campaign["seed"], campaign["patterns"]) == (
        "design", DESIGN_SEED, sum(s.sensor_study is None for s in planned))
    rate = shipped["leave_one_aircraft_out_healthy_rate"]
    assert rate == shipped["training"]["detector"]["design_false_alarms"]
    # the design's healthy lives: 10 cycles of 300-400 flights, three units each
    assert rate["unit_flights"] >= 3 * 10 * 300
    assert rate["rate"] == pytest.approx(rate["events"] / rate["unit_flights"])
    assert rate["interval"][0] <= rate["rate"] <= rate["interval"][1]


def test_a_campaign_other_than_the_shipped_design_is_refused() -> None:
    good = {"kind": "design", "seed": DESIGN_SEED, "scale": DESIGN_SCALE, "noise_scale": 1.0,
            "sensor_faults": [], "bases": None}
    check_design(good, "D")
    for key, value in (("scale", "quick"), ("seed", 2), ("noise_scale", 2.0)):
        with pytest.raises(ValueError, match="shipped design"):
            check_design({**good, key: value}, "D")


# The shipped design takes 16 minutes of both cores to stream, beyond the suite's budget: with
# HMSM_SHIPPED_DESIGN=DIR (a streamed copy, `hmsm campaign --kind design --scale shipped
# --seed 1 --out DIR`) the model is trained again from its stored features (seconds) and
# compared with the shipped one.
@pytest.mark.slow
@pytest.mark.skipif(not os.environ.get("HMSM_SHIPPED_DESIGN"),
                    reason="HMSM_SHIPPED_DESIGN names no streamed shipped design campaign")
def test_the_shipped_demo_model_is_what_its_command_produces() -> None:
    """Training with seed 0 on the shipped design: what ``hmsm demo-model`` does. The RUL
    bands' calibration layers are not training's: ``hmsm calibrate`` fitted them on replays of
    a calibration design (docs/RESULTS.md), so they are checked for provenance only."""
    from server.campaigns import train_from_directory

    design = os.environ["HMSM_SHIPPED_DESIGN"]
    check_design(json.loads((Path(design) / "manifest.json").read_text()), design)
    shipped = load_demo_model()
    model, report = train_from_directory(design, seed=TRAINING_SEED)
    assert_same_document(_without_layers(shipped["payload"]), model.to_dict())
    assert_same_document(shipped["training"], portable_report(report))


def _without_layers(payload: dict[str, Any]) -> dict[str, Any]:
    out = json.loads(json.dumps(payload))
    for spec in out["measurement"].values():
        spec.pop("band_calibration", None)
    return out


def test_the_shipped_calibration_layers_come_from_calibration_runs_kept_apart() -> None:
    """Every progressive mode of the shipped model carries a layer fitted on replays of a
    design campaign other than the one it was trained on."""
    shipped = load_demo_model()
    model = read_model_document(shipped)
    for mode, spec in model.measurement.items():
        layer = spec.band_calibration
        assert layer is not None, mode
        assert layer.n_runs >= 3 and layer.n_records >= 60, mode
        replays = layer.notes["replays"]
        assert replays, mode
        for replay in replays:
            assert replay["kind"] == "design" and replay["seed"] != shipped["design"]["seed"]
        bank = tuple(h.name for h in spec.prognoser.rate_hypotheses) if spec.prognoser else ()
        assert layer.hypotheses == bank, mode  # grouped by the leading hypothesis
        assert layer.weight_split == DEFAULT_WEIGHT_SPLIT, mode  # and its weight


# The same code on another CPU (SIMD and BLAS kernels chosen at run time) differs in the last
# bits, and the fits downstream of the baseline amplify that to ~2e-7; any change of the chain
# moves the model by orders of magnitude more.
RELATIVE_TOLERANCE = 1e-5


def _leaves(doc: Any, path: str = "") -> Iterator[tuple[str, Any]]:
    if isinstance(doc, dict):
        for key, value in doc.items():
            yield from _leaves(value, f"{path}/{key}")
    elif isinstance(doc, list):
        for i, value in enumerate(doc):
            yield from _leaves(value, f"{path}/{i}")
    else:
        yield path, doc


def assert_same_document(expected: Any, actual: Any) -> None:
    """Same keys, same lengths, same strings, integers and flags; floats within
    ``RELATIVE_TOLERANCE``."""
    want, got = dict(_leaves(expected)), dict(_leaves(actual))
    assert sorted(want) == sorted(got)
    for path, value in want.items():
        if isinstance(value, float) and isinstance(got[path], float):
            assert math.isclose(value, got[path], rel_tol=RELATIVE_TOLERANCE,
                                abs_tol=1e-300), path
        else:
            assert value == got[path], path


def test_documents_differing_beyond_the_tolerance_are_told_apart() -> None:
    doc = {"rate": [0.0042, 1.5], "law": "exponential", "runs": 6}
    assert_same_document(doc, {"rate": [0.0042 * (1 + 2e-7), 1.5], "law": "exponential",
                               "runs": 6})
    for other in ({"rate": [0.0042 * (1 + 10 * RELATIVE_TOLERANCE), 1.5], "law": "exponential",
                   "runs": 6},
                  {"rate": [0.0042, 1.5], "law": "affine", "runs": 6},
                  {"rate": [0.0042, 1.5], "law": "exponential", "runs": 7},
                  {"rate": [0.0042], "law": "exponential", "runs": 6}):
        with pytest.raises(AssertionError):
            assert_same_document(doc, other)


def test_the_demo_starts_on_the_shipped_model_without_training(tmp_path) -> None:  # type: ignore[no-untyped-def]
    settings = Settings(data_dir=tmp_path / "demo")
    t0 = time.perf_counter()
    keys = prepare_demo(settings, n_aircraft=10, seed=1)
    assert time.perf_counter() - t0 < 60  # no campaign simulated, nothing trained
    assert set(keys) == {"admin", "maintainer", "operator", "uploader", "viewer"}
    engine = make_engine(settings.effective_database_url)
    with make_session_factory(engine)() as session:
        active = session.scalar(select(ModelVersion).where(ModelVersion.active.is_(True)))
        assert active.payload == load_demo_model()["payload"]
        assert active.metrics["accuracy"] is not None  # the models page has its confusion
        assert len(session.scalars(select(Aircraft)).all()) == 10
        assert len(session.scalars(select(Injection)).all()) == len(DEMO_INJECTIONS)
    engine.dispose()
    assert not (settings.data_dir / "campaigns" / "demo-design").exists()

    # the sim worker flies on the uploader key (the fleet is registered already)
    app = create_app(settings)
    with TestClient(app) as client:
        api = Api("http://testserver", keys["uploader"], operator_key=keys["operator"],
                  sleep=lambda s: None)
        api.client = client
        runner = SimFleetRunner(api, n_aircraft=10, rate_per_min=1e6, seed=1, duration_s=15,
                                sleep=lambda s: None)
        runner.register_fleet()
        assert runner.fly(runner.runs[0]) == "accepted"
    app.state.engine.dispose()


def test_the_sim_worker_reads_its_keys_from_the_environment(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    monkeypatch.setenv("HMSM_SIM_KEY", "hmsm_uploader")
    monkeypatch.setenv("HMSM_SIM_OPERATOR_KEY", "hmsm_operator")
    args = build_parser().parse_args(["run", "--api", "http://127.0.0.1:8000"])
    assert (args.key, args.operator_key) == ("hmsm_uploader", "hmsm_operator")
    monkeypatch.delenv("HMSM_SIM_KEY")
    monkeypatch.delenv("HMSM_SIM_OPERATOR_KEY")
    try:
        build_parser().parse_args(["run", "--api", "http://127.0.0.1:8000"])
    except SystemExit as exc:  # argparse: --key is required without the environment
        assert exc.code == 2
    else:
        raise AssertionError("--key is required when HMSM_SIM_KEY is not set")


def test_a_second_run_of_the_demo_keeps_its_injections(tmp_path) -> None:  # type: ignore[no-untyped-def]
    settings = Settings(data_dir=tmp_path / "demo")
    prepare_demo(settings, n_aircraft=2, seed=1)
    prepare_demo(settings, n_aircraft=2, seed=1)  # the service refuses a second live one
    engine = make_engine(settings.effective_database_url)
    with make_session_factory(engine)() as session:
        rows = session.execute(select(Aircraft.tail, Injection.position, Injection.fault_mode)
                               .join(Aircraft, Aircraft.id == Injection.aircraft_id)).all()
        assert sorted(rows) == [("SIM01", "WL1", "MTWEAR"), ("SIM02", "WT", "DMD")]
    engine.dispose()


def test_an_injection_the_service_refuses_is_not_taken_for_an_earlier_one(  # type: ignore[no-untyped-def]
        tmp_path, monkeypatch) -> None:
    """Only the service's conflict for an existing injection means "injected on an earlier
    run"; any other refusal stops the demo."""
    monkeypatch.setattr("server.demo.DEMO_INJECTIONS", [("SIM01", "WT", "REWEAR", 9, None)])
    with pytest.raises(Unprocessable, match="winglet pair only"):
        prepare_demo(Settings(data_dir=tmp_path / "demo"), n_aircraft=2, seed=1)


def test_the_shipped_models_rate_bounds_admit_every_band_of_its_bank() -> None:
    """Each banked filter of the shipped model, the wingtip's screw wear included (its design
    runs all slow: their own bounds stopped at 110-flight faults)."""
    from server.phm.chain import PhmModel
    from tests.rate_bounds import assert_bounds_admit_the_bank

    model = PhmModel.from_dict(load_demo_model()["payload"])
    banked = 0
    for mode, spec in model.measurement.items():
        for position in ("WL1", "WL2", "WT"):
            cfg = spec.config_for(position)
            if cfg.rate_hypotheses:
                banked += 1
                assert_bounds_admit_the_bank(cfg, f"{mode} {position}")
    assert banked >= 10
