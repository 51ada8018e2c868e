"""The exponential law's mixture rate prior (``PrognoserConfig.rate_prior_tail``)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from server.phm.prognosis import (
    CONSTANTS,
    GENERIC_CONFIG,
    MeasurementModel,
    ParticleFilterPrognoser,
    PrognoserConfig,
    PrognoserState,
    rls_update,
)
from server.phm.prognosis.degradation import rls_update_batch
from server.phm.prognosis.laws import RlsMeasurement
from server.phm.prognosis.mixture import RateMixture

MODEL = MeasurementModel((0.2, 2.0, 0.5), 0.03)  # feature = 0.2 + 2 h + 0.5 h^2 + N(0, 0.03^2)
OFFSET = 0.1
H0 = 0.15  # severity at the first measurement (an alarm)


def _rate(life: float) -> float:
    """r of dh/dk = r (h + c) that takes h from H0 to 1 in ``life`` flights."""
    return float(np.log((1.0 + OFFSET) / (H0 + OFFSET)) / life)


#: a design whose median life is 250 flights, its rates spread by 35 %
PRIOR = replace(GENERIC_CONFIG, rate_basis="exponential", growth_offset=OFFSET,
                initial_theta=(0.0, _rate(250)), initial_rate_std=0.35 * _rate(250),
                rls_forgetting=0.995, process_noise_std=0.01)


def _series(life: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """True severity per flight 0..life (H0 to 1, exponential law) and its measurements."""
    k = np.arange(life + 1, dtype=float)
    h = (H0 + OFFSET) * np.exp(_rate(life) * k) - OFFSET
    z = MODEL.predict(h) + MODEL.noise_std * np.random.default_rng(seed).standard_normal(k.size)
    return h, z


def _track(cfg: PrognoserConfig, z: np.ndarray, until: int, seed: int = 5
           ) -> tuple[ParticleFilterPrognoser, PrognoserState]:
    pf = ParticleFilterPrognoser(cfg, MODEL)
    state = pf.initial_state(cfg, MODEL, seed)
    for k in range(until):
        state = pf.update(state, float(z[k]), k)
    return pf, state


def _band_hits(cfg: PrognoserConfig, life: int, seeds: range) -> float:
    """Share of predictions from a fifth of the life on whose 5-95 % band holds the truth."""
    hits = []
    for seed in seeds:
        _, z = _series(life, seed)
        pf = ParticleFilterPrognoser(cfg, MODEL)
        state = pf.initial_state(cfg, MODEL, seed)
        for k in range(life - 2):
            state = pf.update(state, float(z[k]), k)
            if k >= life // 5 and k % 4 == 0:
                q = pf.predict(state).quantiles
                hits.append(q[0.05] <= life - k <= q[0.95])
    return float(np.mean(hits))


def test_a_fault_five_times_faster_than_the_design_pulls_the_rate_within_a_few_flights() -> None:
    """A 50-flight life under a prior centred on 250: with the mixture the rate is within 30 %
    of the truth after 15 flights, where the normal prior has not left its own range."""
    _, z = _series(50, seed=1)
    truth = _rate(50)
    _, normal = _track(PRIOR, z, 15)
    _, mixed = _track(replace(PRIOR, rate_prior_tail=0.2), z, 15)
    assert normal.theta[1] < 0.5 * truth
    assert mixed.theta[1] == pytest.approx(truth, rel=0.3)
    assert mixed.mixture is not None
    assert mixed.mixture.weights[0] < 0.05  # the design's own component has lost


def test_the_band_holds_a_fast_fault_that_the_normal_prior_misses() -> None:
    tail = replace(PRIOR, rate_prior_tail=0.2)
    assert _band_hits(PRIOR, 50, range(3)) < 0.7
    assert _band_hits(tail, 50, range(3)) >= 0.9


def test_a_fault_at_the_design_rate_keeps_the_weight_on_the_design_component() -> None:
    """In range the tail components lose weight and the prediction stays that of the normal
    prior within a few percent."""
    _, z = _series(250, seed=2)
    pf_n, normal = _track(PRIOR, z, 150)
    pf_m, mixed = _track(replace(PRIOR, rate_prior_tail=0.2), z, 150)
    assert mixed.mixture is not None and mixed.mixture.weights[0] > 0.8
    assert pf_m.predict(mixed).median == pytest.approx(pf_n.predict(normal).median, rel=0.05)
    assert pf_m.predict(mixed).median == pytest.approx(100, rel=0.2)


def test_the_prior_mixture_is_the_normal_prior_and_its_scaled_copies() -> None:
    cfg = replace(PRIOR, rate_prior_tail=0.3)
    mix = cfg.law.prior_mixture(cfg)
    factors = np.r_[1.0, CONSTANTS.rate_tail_factors]
    assert np.allclose(mix.theta[:, 1], PRIOR.theta0[1] * factors)
    assert np.allclose(np.sqrt(mix.cov[:, 1, 1]), PRIOR.rate_prior_std * factors)
    assert mix.weights[0] == pytest.approx(0.7)
    assert np.allclose(mix.weights[1:], 0.3 / factors[1:].size)


def test_identical_components_update_as_one_rls() -> None:
    """K copies of one component: the mixture's moments after the step are that RLS's."""
    theta, cov = np.array([0.2, 0.01]), np.diag([0.5, 1e-4])
    mix = RateMixture(np.tile(theta, (3, 1)), np.tile(cov, (3, 1, 1)), np.log(np.full(3, 1 / 3)))
    step = RlsMeasurement(mix.theta, mix.cov, np.array([3.0, 0.0]), 0.9, 0.995)
    new, resid_var = mix.update(step, 1.2, 10.0, mix.log_weights, 1.0)
    want = rls_update(theta, cov, 1.2, step.phi, step.y, step.forgetting, 10.0)
    got_theta, got_cov = new.moments()
    assert np.allclose(got_theta, want[0]) and np.allclose(got_cov, want[1])
    assert resid_var == pytest.approx(want[2])
    assert np.allclose(new.weights, 1 / 3)


def test_the_components_update_together_as_each_would_alone() -> None:
    """The batched step of K components is K steps of one component each, bit for bit, the
    trace bound included."""
    rng = np.random.default_rng(3)
    theta = rng.normal(size=(5, 2))
    cov = np.stack([np.diag(d) for d in rng.uniform(0.1, 4.0, size=(5, 2))])
    phi, y, lam = np.array([2.5, 0.0]), 0.7, 0.98
    got_theta, got_cov, got_var = rls_update_batch(theta, cov, 0.9, phi, y, lam, 3.0)
    for k in range(5):
        want = rls_update(theta[k], cov[k], 0.9, phi, y, lam, 3.0)
        assert np.array_equal(got_theta[k], want[0]) and np.array_equal(got_cov[k], want[1])
        assert got_var[k] == want[2]


def test_a_mixture_state_restores_bit_for_bit(tmp_path: Path) -> None:
    cfg = replace(PRIOR, rate_prior_tail=0.2)
    _, z = _series(80, seed=3)
    pf, state = _track(cfg, z, 30)
    restored = PrognoserState.from_json(state.to_json())
    state.to_npz(str(tmp_path / "state.npz"))
    from_npz = PrognoserState.from_npz(str(tmp_path / "state.npz"))
    for other in (restored, from_npz):
        a, b = state, other
        for k in range(30, 45):
            a, b = pf.update(a, float(z[k]), k), pf.update(b, float(z[k]), k)
        assert a.mixture is not None and b.mixture is not None
        assert np.array_equal(a.mixture.log_weights, b.mixture.log_weights)
        assert np.array_equal(a.theta, b.theta) and np.array_equal(a.severity, b.severity)
        assert np.array_equal(pf.predict(a).samples, pf.predict(b).samples)


def test_the_tail_is_validated_and_absent_from_documents_without_one() -> None:
    assert "rate_prior_tail" not in PRIOR.to_dict()
    tail = replace(PRIOR, rate_prior_tail=0.2)
    assert PrognoserConfig.from_json(tail.to_json()) == tail
    assert ParticleFilterPrognoser(tail, MODEL).digest != ParticleFilterPrognoser(PRIOR,
                                                                                  MODEL).digest
    for bad in (1.0, -0.1, True):
        with pytest.raises(ValueError, match="rate_prior_tail"):
            replace(PRIOR, rate_prior_tail=bad)
    with pytest.raises(ValueError, match="exponential"):
        replace(GENERIC_CONFIG, rate_prior_tail=0.2)
