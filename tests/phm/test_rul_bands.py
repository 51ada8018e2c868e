"""The online guard and the bands' calibration layer."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from server.phm.prognosis import MeasurementModel, ParticleFilterPrognoser, PrognoserConfig
from server.phm.prognosis.calibration import (
    BandCalibration,
    CalibrationRecord,
    fit_band_calibration,
    widen,
)
from server.phm.prognosis.filter import PrognoserState

C, R0 = 0.3, 0.0045  # the prior's law: about 290 flights from severity 0.05 to 1
BASE = PrognoserConfig(rate_basis="exponential", growth_offset=C, initial_theta=(0.0, R0),
                       initial_rate_std=0.35 * R0, rate_bounds=(2e-4, 0.1),
                       rls_forgetting=0.995)
NOISE = 0.05
MODEL = MeasurementModel.identity(NOISE)


def _life(speed: float, seed: int) -> list[float]:
    """True severities of a fault ``speed`` times faster than the prior's, to failure."""
    rng = np.random.default_rng(seed)
    h = [0.05]
    while h[-1] < 1.0:
        h.append(h[-1] + speed * R0 * (h[-1] + C) * math.exp(0.1 * rng.standard_normal()))
    return h


def _run(config: PrognoserConfig, speed: float, seed: int, start: float = 0.3
         ) -> tuple[PrognoserState, list[tuple[float, dict[float, float]]]]:
    """Filter the life; (last state, [(true RUL, quantiles) from ``start`` of the life])."""
    h = _life(speed, seed)
    life = len(h) - 1
    rng = np.random.default_rng(1000 + seed)
    pf = ParticleFilterPrognoser(config, MODEL)
    state = pf.initial_state(config, MODEL, seed)
    out = []
    for k in range(life):
        state = pf.update(state, h[k] + NOISE * rng.standard_normal(), k)
        if k >= start * life:
            out.append((float(life - k), pf.predict(state).quantiles))
    return state, out


def _coverage(preds: list[tuple[float, dict[float, float]]], lo: float, hi: float) -> float:
    return float(np.mean([q[lo] <= t <= q[hi] for t, q in preds]))


def test_a_guarded_state_round_trips_bit_exactly():
    config = replace(BASE, guard_horizon=5)
    pf = ParticleFilterPrognoser(config, MODEL)
    state = pf.initial_state(config, MODEL, 3)
    for k, z in enumerate((0.1, 0.12, 0.11, 0.15, 0.16, 0.18, 0.2)):
        state = pf.update(state, z, k)
    again = PrognoserState.from_json(state.to_json())
    a, b = pf.update(state, 0.22, 9), pf.update(again, 0.22, 9)
    assert np.array_equal(a.theta, b.theta) and np.array_equal(a.severity, b.severity)
    assert a.guard == b.guard and a.guard is not None and a.guard.pending
    assert pf.predict(a).quantiles == pf.predict(b).quantiles


def test_documents_without_the_guard_read_and_write_as_before():
    doc = BASE.to_dict()
    for key in ("guard_horizon", "guard_gain", "guard_miss_rate"):
        assert key not in doc
    assert PrognoserConfig.from_dict(doc) == BASE
    with pytest.raises(ValueError, match="guard_horizon"):
        replace(BASE, guard_horizon=-1)


def test_the_retired_joint_filter_is_refused_with_its_reason():
    """Its config fields and its states (a rate per particle) name the retirement."""
    from server.phm.prognosis import StaleStateError

    with pytest.raises(ValueError, match="retired"):
        PrognoserConfig.from_dict({**BASE.to_dict(), "joint_rate": True})
    state = ParticleFilterPrognoser.initial_state(BASE, MODEL, 1).to_dict()
    with pytest.raises(StaleStateError, match="retired"):
        PrognoserState.from_dict({**state, "log_rates": [0.0] * BASE.n_particles})


def test_the_guard_widens_a_band_whose_forecasts_miss():
    # a prior far too sure of a rate 5 times too slow, and an RLS that never forgets it: the
    # filter's band misses; the guard sees its forecasts miss and widens
    caged = replace(BASE, initial_rate_std=0.02 * R0, rls_forgetting=1.0,
                    process_noise_std=0.001)
    guarded = replace(caged, guard_horizon=8)
    bare = [p for seed in range(3) for p in _run(caged, 5.0, seed)[1]]
    with_guard = [p for seed in range(3) for p in _run(guarded, 5.0, seed)[1]]
    state, _ = _run(guarded, 5.0, 0)
    assert state.guard is not None and state.guard.missed > 0.3 * state.guard.scored
    assert state.guard.widening_fast > 0.3 and state.guard.missed_fast > state.guard.missed_slow
    assert _coverage(with_guard, 0.05, 0.95) > _coverage(bare, 0.05, 0.95) + 0.2


def test_the_guard_stays_quiet_where_the_filter_is_right():
    state, _ = _run(replace(BASE, guard_horizon=8), 1.0, 0)
    assert state.guard is not None and state.guard.missed <= 0.25 * state.guard.scored


def _records(rng: np.random.Generator, n: int, bias: float, ratio: float
             ) -> list[CalibrationRecord]:
    """Bands 5-95 % of a lognormal with sd 0.3 around a median off the truth by ``bias``
    (log units, a normal scatter of sd 0.3 on top): the band is too narrow for it."""
    out = []
    for _ in range(n):
        y = float(rng.uniform(10, 200))
        med = y * math.exp(bias + 0.3 * rng.standard_normal())
        q = {lv: med * math.exp(0.3 * z) for lv, z in
             ((0.05, -1.645), (0.25, -0.674), (0.5, 0.0), (0.75, 0.674), (0.95, 1.645))}
        out.append(CalibrationRecord(q, ratio, y))
    return out


def _held(layer: BandCalibration, recs: list[CalibrationRecord], lo: float, hi: float
          ) -> float:
    from server.phm.prognosis.predictor import RulDistribution

    hits = []
    for r in recs:
        dist = RulDistribution(0, dict(r.quantiles), math.nan, {10: 0.0}, 0.0, np.zeros(2),
                               np.zeros(1), 0.5, 0.1, rate_ratio=r.rate_ratio)
        q = layer.apply(dist).quantiles
        hits.append(q[lo] <= r.true_rul <= q[hi])
    return float(np.mean(hits))


def _width(layer: BandCalibration, recs: list[CalibrationRecord]) -> float:
    """Mean 90 % width of the layer's bands in log(1 + RUL)."""
    from server.phm.prognosis.predictor import RulDistribution

    out = []
    for r in recs:
        dist = RulDistribution(0, dict(r.quantiles), math.nan, {10: 0.0}, 0.0, np.zeros(2),
                               np.zeros(1), 0.5, 0.1, rate_ratio=r.rate_ratio)
        q = layer.apply(dist).quantiles
        out.append(math.log1p(q[0.95]) - math.log1p(q[0.05]))
    return float(np.mean(out))


def test_the_mondrian_layer_calibrates_each_rate_group_on_fresh_records():
    rng = np.random.default_rng(0)
    # in range: unbiased but too wide for nothing; fast (ratio 3): optimistic by 0.6
    fit = _records(rng, 300, 0.0, 1.0) + _records(rng, 300, 0.6, 3.0)
    layer = fit_band_calibration(fit, edges=(0.5, 2.0))
    assert layer.counts == (0, 300, 300)
    for bias, ratio in ((0.0, 1.0), (0.6, 3.0)):
        fresh = _records(rng, 400, bias, ratio)
        assert 0.85 <= _held(layer, fresh, 0.05, 0.95) <= 0.95
        assert 0.42 <= _held(layer, fresh, 0.25, 0.75) <= 0.58
    # one layer for both (no groups) covers as much only with wider bands: it cannot tell
    # which predictions are biased
    pooled = fit_band_calibration(fit, edges=(1e9,))
    fresh = _records(rng, 400, 0.0, 1.0) + _records(rng, 400, 0.6, 3.0)
    assert _width(pooled, fresh) > 1.15 * _width(layer, fresh)
    assert BandCalibration.from_dict(layer.to_dict()) == layer


def test_widen_keeps_the_median_and_the_order():
    from server.phm.prognosis.predictor import RulDistribution

    q = {0.05: 10.0, 0.25: 20.0, 0.5: 30.0, 0.75: 40.0, 0.95: math.inf}
    dist = RulDistribution(0, q, 30.0, {10: 0.05, 25: 0.2, 50: 0.8}, 0.06, np.zeros(2),
                           np.zeros(1), 0.5, 0.1)
    wide = widen(dist, {0.5: (0.5, 0.5), 0.9: (1.0, 1.0)}).quantiles
    assert wide[0.5] == 30.0 and wide[0.95] == math.inf
    assert wide[0.05] < wide[0.25] < 30.0 < wide[0.75]
    narrow = widen(dist, {0.5: (-2.0, -2.0), 0.9: (-0.1, -0.1)}).quantiles
    assert narrow[0.05] <= narrow[0.25] <= 30.0 <= narrow[0.75] <= narrow[0.95]
