"""The chain's prognosis step (server.phm.chain.prognose) without a trained model: a stored
filter state from another model version restarts the filter, every other error propagates."""

from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from server.phm.chain.model import MeasurementSpec
from server.phm.chain.prognose import prognose
from server.phm.chain.state import ActuatorHealth
from server.phm.detection import DetectionState
from server.phm.prognosis import (
    GENERIC_CONFIG,
    MeasurementModel,
    ParticleFilterPrognoser,
    PrognoserState,
    StaleStateError,
)

MODEL = MeasurementModel((0.2, 2.0, 0.5), 0.03)
CONFIG = replace(GENERIC_CONFIG, n_particles=200)
MODE = "MTWEAR"
FEATURE = "f"


def _model():  # type: ignore[no-untyped-def]
    """The few fields of a PhmModel that prognose reads (flight clock: no climate)."""
    spec = MeasurementSpec(FEATURE, MODEL, prognoser=CONFIG)
    return SimpleNamespace(measurement={MODE: spec}, prognoser=CONFIG, climate=None)


def _health(state: PrognoserState, history: list[tuple[int, dict[str, float]]]) -> ActuatorHealth:
    h = ActuatorHealth(position="WT", detection=DetectionState.new("WT", [FEATURE]),
                       alarm_index=0, fault_mode=MODE, history=history)
    h.prognosis = state.to_dict()
    return h


def _state(config, flights: range):  # type: ignore[no-untyped-def]
    pf = ParticleFilterPrognoser(config, MODEL)
    state = pf.initial_state(config, MODEL, 1)
    for k in flights:
        state = pf.update(state, float(MODEL.predict(np.array([0.1 + 0.01 * k]))[0]), k)
    return state


def _history(flights: range) -> list[tuple[int, dict[str, float]]]:
    return [(k, {FEATURE: float(MODEL.predict(np.array([0.1 + 0.01 * k]))[0])})
            for k in flights]


def test_a_flight_index_that_does_not_increase_raises_instead_of_restarting() -> None:
    h = _health(_state(CONFIG, range(5)), _history(range(5)))
    with pytest.raises(ValueError, match="flight_index must increase") as err:
        prognose(_model(), h, {FEATURE: 0.5}, "WT", 4, base=None, seed=3)
    assert not isinstance(err.value, StaleStateError)


def test_a_state_from_another_config_restarts_the_filter() -> None:
    stale = _state(replace(CONFIG, n_particles=100), range(5))
    h = _health(stale, _history(range(5)))
    rul = prognose(_model(), h, {FEATURE: 0.5}, "WT", 5, base=None, seed=3)
    assert rul is not None
    restarted = PrognoserState.from_dict(h.prognosis or {})
    assert restarted.config_digest != stale.config_digest
    assert restarted.severity.size == CONFIG.n_particles
    assert restarted.flight_index == 4  # replayed over the stored history


def test_a_state_of_another_format_restarts_the_filter() -> None:
    h = _health(_state(CONFIG, range(5)), _history(range(5)))
    h.prognosis = {**(h.prognosis or {}), "version": 0}
    with pytest.raises(StaleStateError):
        PrognoserState.from_dict(h.prognosis)
    assert prognose(_model(), h, {FEATURE: 0.5}, "WT", 5, base=None, seed=3) is not None
    assert (h.prognosis or {})["version"] == 1
