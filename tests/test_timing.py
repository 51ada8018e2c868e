"""The stage clock: stages timed around calls, and a block whose inner stages are set apart
(how the worker splits the PHM chain's one call into detection, classification and
prognosis: the chain times the last two itself)."""

from __future__ import annotations

import time

import pytest

from server.timing import StageClock


def test_rest_is_the_block_less_the_stages_timed_inside_it() -> None:
    clock = StageClock()
    with clock.rest("rest"):
        with clock.stage("inner"):
            time.sleep(0.02)
        time.sleep(0.01)
    assert 0.018 < clock.seconds["inner"] < 0.2
    assert 0.008 < clock.seconds["rest"] < 0.1


def test_a_stage_that_raises_is_timed() -> None:
    clock = StageClock()
    with pytest.raises(RuntimeError), clock.rest("rest"), clock.stage("raises"):
        time.sleep(0.01)
        raise RuntimeError("boom")
    assert clock.seconds["raises"] > 0.008 and clock.seconds["rest"] >= 0.0


def test_stages_add_up_and_refuse_impossible_durations() -> None:
    clock = StageClock()
    for _ in range(3):
        with clock.stage("decode"):
            time.sleep(0.005)
    assert clock.seconds["decode"] >= 0.015
    for bad in (-1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError):
            clock.add("decode", bad)


def test_the_chain_is_split_into_detection_classification_and_prognosis(shipped_model) -> None:  # type: ignore[no-untyped-def]
    """On the chain itself: ``analyze_flight`` times its classification and prognosis, the
    rest of the call is detection (the factory's sinusoid flights look faulty to the shipped
    model: alarms within a few flights)."""
    from server.phm.chain import analyze_flight, read_model_document
    from server.phm.recording import log_features
    from tests.flightlog_factory import make_log

    model = read_model_document(shipped_model[0])
    health = {p: model.new_health(p) for p in ("WL1", "WL2", "WT")}
    clock = StageClock()
    ruls = 0
    for i in range(5):
        features = log_features(make_log("T1", f"F{i}", seed=i, duration_s=20))
        with clock.rest("detection"):
            out = analyze_flight(model, features, health, seed=i, stage=clock.stage)
        ruls += sum(o.rul is not None for o in out.values())
    assert ruls > 0, "the test flights no longer reach prognosis: choose others"
    assert set(clock.seconds) == {"detection", "classification", "prognosis"}
    assert all(v > 0 for v in clock.seconds.values()), clock.seconds
