"""The stage clock: a block timed as a whole, the time inside watched functions set apart as
their own stages (how the worker splits the PHM chain's one call into detection,
classification and prognosis without touching the chain's code)."""

from __future__ import annotations

import sys
import time

import pytest

from server.timing import StageClock


def _inner() -> None:
    time.sleep(0.02)


def _outer() -> None:
    _inner()
    time.sleep(0.01)


def _raises() -> None:
    time.sleep(0.01)
    raise RuntimeError("boom")


def test_split_sets_the_watched_functions_apart_and_the_rest_to_the_block() -> None:
    clock = StageClock()
    with clock.split("rest", {_outer.__code__: "outer", _inner.__code__: "inner"}):
        _outer()  # _inner runs inside _outer: counted once, for the outer
        time.sleep(0.01)
        _inner()  # on its own: its stage
    assert set(clock.seconds) == {"outer", "inner", "rest"}
    assert 0.03 <= clock.seconds["outer"] < 0.3
    assert 0.02 <= clock.seconds["inner"] < 0.3
    assert 0.01 <= clock.seconds["rest"] < 0.3
    assert sys.getprofile() is None  # the hook is gone after the block


def test_a_watched_function_that_raises_is_timed_and_the_hook_removed() -> None:
    clock = StageClock()
    with pytest.raises(RuntimeError), clock.split("rest", {_raises.__code__: "raises"}):
        _raises()
    assert clock.seconds["raises"] >= 0.01 and "rest" in clock.seconds
    assert sys.getprofile() is None


def test_someone_elses_profiler_is_left_alone_and_nothing_recorded() -> None:
    calls = []

    def theirs(frame, event, arg):  # type: ignore[no-untyped-def]
        calls.append(event)

    clock = StageClock()
    sys.setprofile(theirs)
    try:
        with clock.split("rest", {_inner.__code__: "inner"}):
            _inner()
        assert sys.getprofile() is theirs
    finally:
        sys.setprofile(None)
    assert clock.seconds == {} and calls


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
    """On the chain itself: the names the service watches still exist in
    ``server.phm.chain.run`` and take the time of classification and prognosis (the factory's
    sinusoid flights look faulty to the shipped model: alarms within a few flights)."""
    from server.campaigns import log_features
    from server.phm.chain import analyze_flight, read_model_document
    from server.services.analysis import CHAIN_STAGES
    from tests.flightlog_factory import make_log

    assert sorted(CHAIN_STAGES.values()) == ["classification", "prognosis"]
    model = read_model_document(shipped_model[0])
    health = {p: model.new_health(p) for p in ("WL1", "WL2", "WT")}
    clock = StageClock()
    ruls = 0
    for i in range(5):
        features = log_features(make_log("T1", f"F{i}", seed=i, duration_s=20))
        with clock.split("detection", CHAIN_STAGES):
            out = analyze_flight(model, features, health, seed=i)
        ruls += sum(o.rul is not None for o in out.values())
    assert ruls > 0, "the test flights no longer reach prognosis: choose others"
    assert set(clock.seconds) == {"detection", "classification", "prognosis"}
    assert all(v > 0 for v in clock.seconds.values()), clock.seconds
