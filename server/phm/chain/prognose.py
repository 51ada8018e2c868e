"""The prognosis step of one actuator after an alarm: per progressive mode present, carry its
particle filter one flight on, or restart it from the stored history (a mode new to the set, a
new model), and predict its RUL; the unit's RUL is its earliest failure among them."""

from __future__ import annotations

import math
from datetime import datetime
from typing import Any

import numpy as np

from server.vocabulary import PROGRESSIVE

from ..prognosis import (
    ParticleFilterPrognoser,
    PrognoserState,
    RulDistribution,
    StaleStateError,
    growth_onset,
)
from ..season import StressClock
from .model import MeasurementSpec, PhmModel
from .state import ActuatorHealth

__all__ = ["prognose", "prognose_modes", "earliest"]

History = list[tuple[int, dict[str, float]]]


def prognose_modes(model: PhmModel, h: ActuatorHealth, generic: dict[str, float],
                   position: str, index: int, *, base: str | None, seed: int
                   ) -> dict[str, RulDistribution]:
    """Each progressive mode present's RUL (``h.modes``, the leading one first); the filters
    of modes no longer present are dropped."""
    h.prognoses = {m: s for m, s in h.prognoses.items() if m in h.modes}
    out = {}
    for mode in h.modes:
        rul = prognose(model, h, generic, position, index, base=base, seed=seed, mode=mode)
        if rul is not None:
            out[mode] = rul
    return out


def earliest(ruls: dict[str, RulDistribution]) -> tuple[str | None, RulDistribution | None]:
    """The unit's RUL: the mode whose median failure comes first, with its distribution (the
    first in order on a tie: the leading mode); (None, None) without any."""
    if not ruls:
        return None, None
    mode = min(ruls, key=lambda m: ruls[m].median)
    return mode, ruls[mode]


def prognose(model: PhmModel, h: ActuatorHealth, generic: dict[str, float], position: str,
             index: int, *, base: str | None, seed: int, mode: str | None = None
             ) -> RulDistribution | None:
    """RUL of an alarmed actuator for ``mode`` (default its leading one) when it is a
    progressive mode the model can track (None otherwise); ``h.prognoses[mode]`` holds the
    filter state afterwards."""
    mode = h.fault_mode if mode is None else mode
    if mode not in PROGRESSIVE or mode not in model.measurement:
        return None
    spec = model.measurement[mode]
    pf = ParticleFilterPrognoser(spec.config_for(position) or model.prognoser,
                                 spec.model_for(position))
    clock = _stress_clock(model, spec, h, base, index)
    state, rul = _continue(pf, spec, h.prognoses.get(mode), generic, index, clock)
    if state is None:
        state = _restart(model, spec, h, mode, position, seed, clock)
        rul = None if state is None else _predict(pf, state, index, clock)
    if state is not None:
        h.prognoses[mode] = state.to_dict()
    if rul is not None and spec.band_calibration is not None:
        rul = spec.band_calibration.apply(rul)
    return rul


def _continue(pf: ParticleFilterPrognoser, spec: MeasurementSpec, stored: dict[str, Any] | None,
              generic: dict[str, float], index: int, clock: StressClock | None
              ) -> tuple[PrognoserState | None, RulDistribution | None]:
    """The stored filter updated with this flight's measurement; (None, None) when there is
    none, or it belongs to another model version (a new model was activated). Any other
    error (a flight index that does not increase, a non-finite stress) propagates."""
    if stored is None:
        return None, None
    try:
        state = PrognoserState.from_dict(stored)
        value = generic.get(spec.feature)
        if value is not None and math.isfinite(value):
            state = pf.update(state, value, index, stress=_stress(clock, state, index))
        return state, _predict(pf, state, index, clock)
    except StaleStateError:
        return None, None


def _restart(model: PhmModel, spec: MeasurementSpec, h: ActuatorHealth, mode: str,
             position: str, seed: int, clock: StressClock | None) -> PrognoserState | None:
    """A new filter replayed over the history since the alarm (or since the growth's onset,
    for modes that grow along a straight line)."""
    since = h.alarm_index if h.alarm_index is not None else -1
    if spec.replay_from_onset:
        since = min(since, _growth_onset(spec, position, h.history))
    return _replay(model, mode, position,
                   [(i, v) for i, v in h.history if i >= since], seed, clock)


def _replay(model: PhmModel, mode: str, position: str, history: History, seed: int,
            clock: StressClock | None) -> PrognoserState | None:
    spec = model.measurement.get(mode)
    if spec is None:
        return None
    config = spec.config_for(position) or model.prognoser
    pf = ParticleFilterPrognoser(config, spec.model_for(position))
    state = ParticleFilterPrognoser.initial_state(config, spec.model_for(position), seed)
    for index, z in history:
        value = z.get(spec.feature)
        if value is not None and math.isfinite(value):
            state = pf.update(state, value, index, stress=_stress(clock, state, index))
    return state


def _growth_onset(spec: MeasurementSpec, position: str, history: History) -> int:
    """The flight at which the mode's fault began to grow, from the inverted measurements of
    the actuator's stored history (:func:`~server.phm.prognosis.onset.growth_onset`)."""
    points = [(i, z[spec.feature]) for i, z in history
              if spec.feature in z and math.isfinite(z[spec.feature])]
    if not points:
        return history[-1][0] if history else 0
    severity = spec.model_for(position).invert(np.array([v for _, v in points]))
    return growth_onset([i for i, _ in points], severity)


def _stress_clock(model: PhmModel, spec: MeasurementSpec, h: ActuatorHealth, base: str | None,
                  index: int) -> StressClock | None:
    """The mode's stress clock for this aircraft, anchored at the current flight; None (a
    flight clock) for a mode without temperature sensitivity, an unknown base or date."""
    if (spec.stress_beta_per_k == 0.0 or model.climate is None or not model.climate.knows(base)
            or h.last_started_at is None or not h.flights_per_day):
        return None
    return StressClock(model.climate, str(base), spec.stress_beta_per_k, spec.stress_ref_c,
                       datetime.fromisoformat(h.last_started_at), index, h.flights_per_day)


def _stress(clock: StressClock | None, state: PrognoserState, index: int) -> float | None:
    if clock is None or state.flight_index is None:
        return None
    return clock.between(state.flight_index, index)


def _predict(pf: ParticleFilterPrognoser, state: PrognoserState, index: int,
             clock: StressClock | None) -> RulDistribution:
    if clock is None or state.flight_index is None:
        return pf.predict(state, at_flight=index)
    curve = clock.curve(state.flight_index, pf.config.max_horizon_flights)
    return pf.predict(state, at_flight=index, stress_curve=curve)
