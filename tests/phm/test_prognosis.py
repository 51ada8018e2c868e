"""Particle-filter prognoser (server.phm.prognosis): seeded, with tolerances."""

from __future__ import annotations

import json
import math
import typing
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from server.phm.prognosis import (
    CONSTANTS,
    GENERIC_CONFIG,
    LAWS,
    RATE_BASES,
    AffineLaw,
    ConstantLaw,
    DegradationLaw,
    ExponentialLaw,
    MeasurementModel,
    ParticleFilterPrognoser,
    PrognoserConfig,
    PrognoserState,
    QuadraticLaw,
    RateBasis,
    RulDistribution,
    effective_sample_size,
    law_for,
    systematic_resample,
)

MODEL = MeasurementModel((0.2, 2.0, 0.5), 0.03)  # feature = 0.2 + 2 h + 0.5 h^2 + N(0, 0.03^2)


def _config(**changes: object) -> PrognoserConfig:
    """The generic interface's config (process noise 0.004, the one these synthetic series
    were measured with) with ``changes``."""
    return replace(GENERIC_CONFIG, **changes)


def _truth(law: str, life: int, h0: float = 0.1) -> np.ndarray:
    """True severity per flight 0..life, reaching exactly 1.0 at flight ``life``."""
    k = np.arange(life + 1, dtype=float)
    if law == "exp":
        return h0 * np.exp(np.log(1.0 / h0) * k / life)
    if law == "lin":
        return h0 + (1.0 - h0) * k / life
    if law == "pow":
        return h0 + (1.0 - h0) * (k / life) ** 2
    raise ValueError(law)


@pytest.mark.parametrize(
    ("law", "life", "seed"), [("exp", 200, 1), ("lin", 250, 2), ("pow", 180, 3)]
)
def test_rul_converges_to_truth(law: str, life: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    h = _truth(law, life)
    z = MODEL.predict(h) + MODEL.noise_std * rng.standard_normal(h.size)
    cfg = _config()
    pf = ParticleFilterPrognoser(cfg, MODEL)
    state = pf.initial_state(cfg, MODEL, seed)
    rel_err, covered = [], []
    for k in range(life):
        state = pf.update(state, z[k], k)
        # last half of life, leaving out the final 5 flights (RUL of a few flights)
        if life // 2 <= k < life - 5 and k % 2 == 0:
            dist = pf.predict(state)
            true_rul = life - k
            rel_err.append((dist.median - true_rul) / true_rul)
            covered.append(dist.quantiles[0.05] <= true_rul <= dist.quantiles[0.95])
    rel_err_a = np.abs(np.array(rel_err))
    assert np.mean(rel_err_a <= 0.2) >= 0.7, rel_err
    assert np.median(rel_err_a) <= 0.15
    assert np.mean(covered) >= 0.8


def test_resampling_only_when_ess_below_half() -> None:
    rng = np.random.default_rng(5)
    h = _truth("exp", 120)
    z = MODEL.predict(h) + MODEL.noise_std * rng.standard_normal(h.size)
    cfg = _config(n_particles=200)
    pf = ParticleFilterPrognoser(cfg, MODEL)
    state = pf.initial_state(cfg, MODEL, 11)
    seen = {True: 0, False: 0}
    for k in range(120):
        prev = state
        state = pf.update(state, z[k], k)
        if k == 0:
            continue
        assert state.resampled == (state.last_ess < 0.5 * cfg.n_particles)
        seen[state.resampled] += 1
        if state.resampled:
            np.testing.assert_allclose(state.weights, 1.0 / cfg.n_particles)
        else:
            assert state.n_resamples == prev.n_resamples
    assert seen[True] > 0 and seen[False] > 0


def test_systematic_resample_counts() -> None:
    rng = np.random.default_rng(0)
    w = rng.random(50)
    w /= w.sum()
    idx = systematic_resample(w, rng)
    counts = np.bincount(idx, minlength=50)
    # systematic resampling keeps each count within floor/ceil of N w_i (+-1)
    assert np.all(np.abs(counts - 50 * w) < 1.0 + 1e-9)
    one_hot = np.zeros(10)
    one_hot[3] = 1.0
    assert np.all(systematic_resample(one_hot, rng) == 3)
    assert effective_sample_size(np.full(8, 1 / 8)) == pytest.approx(8.0)
    assert effective_sample_size(one_hot) == pytest.approx(1.0)


def _run(
    pf: ParticleFilterPrognoser, state: PrognoserState, z: np.ndarray, k0: int, k1: int
) -> PrognoserState:
    for k in range(k0, k1):
        state = pf.update(state, z[k], k, flight_hours=1.5)
    return state


def test_serialise_restore_gives_identical_outputs(tmp_path: Path) -> None:
    rng = np.random.default_rng(9)
    h = _truth("lin", 100)
    z = MODEL.predict(h) + MODEL.noise_std * rng.standard_normal(h.size)
    cfg = _config()
    pf = ParticleFilterPrognoser(cfg, MODEL)
    state = _run(pf, pf.initial_state(cfg, MODEL, 4), z, 0, 40)
    text = state.to_json()
    json.loads(text)  # plain JSON, no NaN/Infinity
    restored = PrognoserState.from_json(text)
    state.to_npz(str(tmp_path / "state.npz"))
    from_npz = PrognoserState.from_npz(str(tmp_path / "state.npz"))
    # also the config and the measurement model travel as JSON
    pf2 = ParticleFilterPrognoser(
        PrognoserConfig.from_json(cfg.to_json()), MeasurementModel.from_json(MODEL.to_json())
    )
    a = _run(pf, state, z, 40, 70)
    b = _run(pf2, restored, z, 40, 70)
    c = _run(pf, from_npz, z, 40, 70)
    for other in (b, c):
        assert np.array_equal(a.severity, other.severity)
        assert np.array_equal(a.log_weights, other.log_weights)
        assert np.array_equal(a.theta, other.theta) and np.array_equal(a.cov, other.cov)
        assert a.rng_state == other.rng_state
    da, db = pf.predict(a), pf2.predict(b)
    assert da.quantiles == db.quantiles
    assert np.array_equal(da.samples, db.samples)
    # the RUL distribution itself round-trips through JSON
    back = RulDistribution.from_json(da.to_json(include_samples=True))
    assert back.quantiles == da.quantiles and np.array_equal(back.samples, da.samples)


def test_predict_is_pure_and_repeatable() -> None:
    cfg = _config(n_particles=100)
    pf = ParticleFilterPrognoser(cfg, MODEL)
    state = pf.initial_state(cfg, MODEL, 1)
    for k, s in enumerate(np.linspace(0.2, 0.4, 20)):
        state = pf.update(state, float(MODEL.predict(s)), k, flight_hours=2.0)
    before = state.to_json()
    d1, d2 = pf.predict(state), pf.predict(state)
    assert state.to_json() == before
    assert d1.quantiles == d2.quantiles
    assert d1.hours_per_flight == pytest.approx(2.0)
    assert d1.quantiles_hours()[0.5] == pytest.approx(2.0 * d1.median)
    levels = list(d1.quantiles)
    assert levels == [0.05, 0.25, 0.5, 0.75, 0.95]
    qs = [d1.quantiles[q] for q in levels]
    assert qs == sorted(qs)
    p = [d1.p_fail_within[h] for h in (10, 25, 50)]
    assert p == sorted(p) and 0.0 <= p[0] and p[-1] <= 1.0
    assert d1.histogram_mass.sum() + d1.p_beyond_horizon == pytest.approx(1.0)


def test_prediction_at_a_flight_without_measurement_counts_the_flights_since() -> None:
    """Flights that bring no value of the feature still use up life: the RUL seen at a later
    flight is the last update's RUL less the flights since, floored at 0."""
    cfg = _config(n_particles=100)
    pf = ParticleFilterPrognoser(cfg, MODEL)
    state = pf.initial_state(cfg, MODEL, 1)
    for k, s in enumerate(np.linspace(0.2, 0.4, 20)):
        state = pf.update(state, float(MODEL.predict(s)), k)
    now = pf.predict(state)
    later = pf.predict(state, at_flight=19 + 30)
    assert later.flight_index == 49 and now.flight_index == 19
    np.testing.assert_allclose(later.samples, np.maximum(now.samples - 30, 0.0))
    assert later.median == pytest.approx(max(now.median - 30, 0.0), abs=1.0)
    assert later.p_fail_within[10] >= now.p_fail_within[10]
    with pytest.raises(ValueError, match="before the last update"):
        pf.predict(state, at_flight=10)


def test_rate_bounds_keep_the_tuned_law_plausible() -> None:
    """A flat, noisy stretch drives the RLS towards a near-zero rate (RUL beyond the horizon);
    bounded, the mid-life rate of every particle's law in the prediction stays in range."""
    rng = np.random.default_rng(7)
    z = MODEL.predict(np.full(60, 0.2)) + MODEL.noise_std * rng.standard_normal(60)
    lo, hi = 1.0 / 400, 1.0 / 100
    free_cfg = _config(initial_theta=(0.004, 0.002))
    bounded_cfg = _config(initial_theta=(0.004, 0.002), rate_bounds=(lo, hi))
    meds = {}
    for name, cfg in (("free", free_cfg), ("bounded", bounded_cfg)):
        pf = ParticleFilterPrognoser(cfg, MODEL)
        st = pf.initial_state(cfg, MODEL, 3)
        for k in range(60):
            st = pf.update(st, z[k], k)
        meds[name] = pf.predict(st).median
        if name == "bounded":
            samples = pf.parameter_samples(st, np.random.default_rng(0))
            assert np.all(samples @ np.array([1.0, 0.5]) <= hi * (1 + 1e-9))
            assert np.all(samples @ np.array([1.0, 0.5]) >= lo * (1 - 1e-9))
    # from severity ~0.2 at the slowest plausible rate the RUL is at most ~0.8 / lo flights
    assert meds["bounded"] <= 1.1 * 0.8 / lo < meds["free"]


def test_config_validation() -> None:
    bad = [
        {"n_particles": 1},
        {"n_particles": 2.5},
        {"process_noise_std": 0.0},
        {"rate_basis": "cubic"},
        {"initial_theta": (0.1,)},  # affine needs 2
        {"rls_forgetting": 1.5},
        {"resample_threshold": 0.0},
        {"quantile_levels": (0.5, 0.05)},
        {"pof_horizons_flights": (0,)},
        {"max_horizon_flights": 0},
        {"rate_bounds": (0.01, 0.001)},
        {"rate_bounds": (0.0, 0.01)},
        {"growth_offset": 0.0},
        {"growth_offset": -0.8},  # would stop growing before the threshold
    ]
    for kwargs in bad:
        with pytest.raises(ValueError):
            PrognoserConfig(**kwargs)
    cfg = _config(rate_basis="quadratic", initial_theta=(0.004, 0.0, 0.001),
                          rate_bounds=(0.002, 0.01))
    assert PrognoserConfig.from_json(cfg.to_json()) == cfg
    with pytest.raises(ValueError):
        PrognoserConfig.from_dict({**cfg.to_dict(), "version": 2})
    with pytest.raises(ValueError):
        MeasurementModel((0.0, 1.0), 0.0)
    with pytest.raises(ValueError):
        MeasurementModel((0.0, 1.0, -1.0), 0.1)  # slope changes sign at s = 0.5


def test_prognoser_rejects_foreign_state_and_time_going_back() -> None:
    cfg = _config(n_particles=50)
    pf = ParticleFilterPrognoser(cfg, MODEL)
    other = ParticleFilterPrognoser(cfg, MeasurementModel((0.0, 1.0), 0.05))
    state = pf.update(pf.initial_state(cfg, MODEL, 0), 0.5, 3)
    with pytest.raises(ValueError):
        other.update(state, 0.5, 4)
    with pytest.raises(ValueError):
        pf.update(state, 0.5, 3)
    with pytest.raises(ValueError):
        pf.update(state, float("nan"), 4)


def test_measurement_model_fit_and_json() -> None:
    rng = np.random.default_rng(2)
    s = rng.uniform(0.0, 1.2, 400)
    f = 0.1 + 2.0 * s + 0.5 * s**2 + 0.02 * rng.standard_normal(s.size)
    mm = MeasurementModel.fit(s, f, degree=2)
    np.testing.assert_allclose(mm.coefficients, (0.1, 2.0, 0.5), atol=0.03)
    assert mm.noise_std == pytest.approx(0.02, rel=0.15)
    assert MeasurementModel.from_json(mm.to_json()) == mm
    grid = np.linspace(-0.2, 2.0, 23)  # includes the linear continuation outside the range
    np.testing.assert_allclose(mm.invert(mm.predict(grid)), grid, atol=2e-3)
    # a decreasing feature works as well
    dec = MeasurementModel.fit(s, 1.0 - 0.8 * s + 0.01 * rng.standard_normal(s.size), degree=3)
    assert np.all(np.diff(dec.predict(np.linspace(0, 1.5, 50))) < 0)


def test_measurement_noise_growing_with_severity_is_fitted_and_normalised() -> None:
    rng = np.random.default_rng(5)
    s = rng.uniform(0.0, 1.1, 600)
    scale = 1e-4  # a feature in metres, as F_MTWEAR
    f = scale * (0.2 * s + (0.004 + 0.02 * s) * rng.standard_normal(s.size))
    mm = MeasurementModel.fit(s, f, noise="linear")
    assert mm.noise_std == pytest.approx(0.004 * scale, rel=0.25)
    assert mm.noise_slope == pytest.approx(0.02 * scale, rel=0.15)
    np.testing.assert_allclose(mm.noise_at([0.0, 1.0, 9.0]),
                               mm.noise_std + mm.noise_slope * np.array([0.0, 1.0, 1.5]))
    assert MeasurementModel.from_json(mm.to_json()) == mm
    # the log-likelihood is a normalised density in the feature whatever the severity
    z = np.linspace(-0.5, 1.0, 30001) * scale
    for sev in (0.1, 0.9):
        dens = np.exp([float(mm.log_likelihood(v, np.array([sev]))[0]) for v in z])
        area = float(np.sum(dens) * (z[1] - z[0]))
        assert area == pytest.approx(np.sqrt(2 * np.pi) * mm.noise_std, rel=1e-3)
    # homoscedastic data: the slope stays near 0 and sigma near the constant fit's
    g = 0.2 * s + 0.01 * rng.standard_normal(s.size)
    const = MeasurementModel.fit(s, g)
    lin = MeasurementModel.fit(s, g, noise="linear")
    assert lin.noise_slope < 0.2 * const.noise_std
    assert lin.noise_at(0.5) == pytest.approx(const.noise_std, rel=0.1)
    with pytest.raises(ValueError, match="noise"):
        MeasurementModel.fit(s, g, noise="student")


def test_measurement_model_reads_version_1_documents() -> None:
    old = {"version": 1, "kind": "polynomial_gaussian", "coefficients": [0.0, 0.2],
           "noise_std": 0.01, "severity_range": [0.0, 1.5]}
    mm = MeasurementModel.from_dict(old)
    assert mm.noise_slope == 0.0 and mm.to_dict()["version"] == 2
    with pytest.raises(ValueError, match="unsupported"):
        MeasurementModel.from_dict({**old, "version": 3})


def test_filter_on_a_decreasing_indicator_normalised_to_severity() -> None:
    """A capacity-like indicator 100 -> 70 (threshold) linearly over 150 flights, noise 0.5,
    normalised to a severity (x - 100) / (70 - 100) with its noise: the median RUL after 120
    flights within 25 % of the truth, inside the 5-95 % band; quantiles by fraction or percent;
    flight hours carried."""
    rng = np.random.default_rng(8)
    life = 150
    k = np.arange(120)
    x = 100.0 - 30.0 * k / life + 0.5 * rng.standard_normal(k.size)
    severity = (x - 100.0) / (70.0 - 100.0)
    cfg = _config()
    model = MeasurementModel.identity(0.5 / 30.0)
    pf = ParticleFilterPrognoser(cfg, model)
    state = pf.initial_state(cfg, model, 3)
    for i in k:
        state = pf.update(state, float(severity[i]), int(i), flight_hours=1.2)
    dist = pf.predict(state)
    true_rul = life - k[-1]
    assert abs(dist.median - true_rul) <= 0.25 * true_rul
    assert dist.quantiles[0.05] <= true_rul <= dist.quantiles[0.95]
    assert dist.hours_per_flight == pytest.approx(1.2)
    assert dist.percentile(5) == dist.quantile(0.05) == dist.quantiles[0.05]
    assert dist.quantiles[0.25] <= dist.quantile(0.3) <= dist.quantiles[0.75]
    assert 0.0 <= dist.p_beyond_horizon <= 1.0
    with pytest.raises(ValueError, match="percentile"):
        dist.quantile(5)


def test_whole_numbers_given_as_floats_are_counts() -> None:
    cfg = PrognoserConfig(n_particles=500.0, max_horizon_flights=2000.0,  # type: ignore[arg-type]
                          pof_horizons_flights=(10.0, 25))  # type: ignore[arg-type]
    assert cfg.n_particles == 500 and isinstance(cfg.n_particles, int)
    assert cfg.pof_horizons_flights == (10, 25)
    for bad in (500.5, True, "500"):
        with pytest.raises(ValueError, match="whole number"):
            PrognoserConfig(n_particles=bad)  # type: ignore[arg-type]


def test_saturating_law_tracks_growth_that_slows_down() -> None:
    """dh/dk = r (h + c) with c < -1, r < 0: wear whose rate falls as it grows (a worn
    winglet drive handing its load to its partner). The level RLS finds r from a wrong first
    trial and the RUL of the last half of life comes within the alpha = 0.2 cone."""
    big_c, h0, life = 1.5, 0.05, 220
    mu = np.log((big_c - h0) / (big_c - 1.0)) / life
    k = np.arange(life + 1, dtype=float)
    h = big_c - (big_c - h0) * np.exp(-mu * k)
    rng = np.random.default_rng(7)
    z = MODEL.predict(h) + MODEL.noise_std * rng.standard_normal(h.size)
    cfg = _config(rate_basis="exponential", growth_offset=-big_c,
                          initial_theta=(0.0, -0.6 * mu), initial_rate_std=0.5 * mu,
                          rls_forgetting=0.995)
    pf = ParticleFilterPrognoser(cfg, MODEL)
    state = pf.initial_state(cfg, MODEL, 3)
    rel_err = []
    for i in range(life):
        state = pf.update(state, z[i], i)
        if life // 2 <= i < life - 10 and i % 5 == 0:
            rel_err.append((pf.predict(state).median - (life - i)) / (life - i))
    assert state.theta[1] == pytest.approx(-mu, rel=0.25)
    assert np.mean(np.abs(rel_err) <= 0.2) >= 0.7, rel_err


@pytest.mark.parametrize("model", [MODEL, MeasurementModel((1.0, -0.8, -0.3), 0.05, (0.0, 1.5),
                                                           noise_slope=0.02)])
def test_scalar_measurement_helpers_match_the_array_ones(model: MeasurementModel) -> None:
    """The filter's per-update floats (invert_one, severity_noise) equal the vectorised
    methods, inside the fitted range and on its linear continuations."""
    s = np.array([-0.3, 0.0, 0.2, 0.77, 1.5, 2.1])
    z = model.predict(s)
    for si, zi in zip(s, z, strict=True):
        assert model.invert_one(float(zi)) == pytest.approx(float(model.invert(zi)), abs=1e-12)
        want = float(model.noise_at(si)) / abs(float(model.derivative(si)))
        assert model.severity_noise(float(si)) == pytest.approx(want, rel=1e-12)


def _numpy_propagation(h, theta, min_rate, step, block, noise_blocks, horizon):
    """The prediction loop as it was before it was compiled, for the comparison below."""
    h = h.copy()
    rul = np.full(h.size, np.inf)
    cap, t, i, b = 5.0, 0.0, 0, 0
    noise = noise_blocks[0]
    while t < horizon:
        if i == block:
            i, b, step = 0, b + 1, step * 2
            noise = noise_blocks[b]
        dt = min(float(step), horizon - t)
        rate = np.maximum(theta[:, 0] + theta[:, 1] * h, min_rate)
        new = h + rate * dt + np.sqrt(dt) * noise[i]
        crossed = (new >= 1.0) & (h < 1.0)
        rul[crossed] = t + dt * (1.0 - h[crossed]) / (new[crossed] - h[crossed])
        new[crossed] = cap
        if np.isfinite(rul).all():
            break
        h = np.clip(new, 0.0, cap)
        t += dt
        i += 1
    return rul


def test_compiled_prediction_loop_matches_the_numpy_one() -> None:
    from server.phm.prognosis.predictor import propagate_to_threshold

    cfg = _config(prediction_steps=20, max_horizon_flights=400)
    rng = np.random.default_rng(11)
    h = rng.uniform(0.2, 0.6, 200)
    theta = np.column_stack([rng.uniform(0.0, 0.006, 200), rng.uniform(-0.004, 0.004, 200)])
    got = propagate_to_threshold(h, theta, cfg, np.random.default_rng(5))
    # the same draws: one block of (prediction_steps, N) normals per block of steps
    draws = np.random.default_rng(5)
    blocks = [cfg.process_noise_std * draws.standard_normal((20, 200)) for _ in range(10)]
    h_ref = float(h.mean())
    rate_ref = max(float(theta[:, 0].mean() + theta[:, 1].mean() * h_ref), cfg.min_rate)
    step = max(1, int(np.ceil(min((1.0 - h_ref) / rate_ref, 400.0) / 20)))
    want = _numpy_propagation(h, theta, cfg.min_rate, step, 20, blocks, 400.0)
    assert np.isinf(got).any() and np.isfinite(got).any()  # both outcomes exercised
    np.testing.assert_allclose(got, want, rtol=1e-12)


def test_most_probable_rul_finds_the_mode_of_a_skewed_distribution() -> None:
    from server.phm.prognosis.predictor import most_probable_rul

    rng = np.random.default_rng(4)
    # gamma(k=4, scale=10): mode 30, median about 36.7 -- the mode lies below the median
    r = rng.gamma(4.0, 10.0, 4000)
    w = np.full(r.size, 1.0 / r.size)
    mode = most_probable_rul(r, w)
    assert 26.0 < mode < 34.0
    assert mode < float(np.median(r)) - 3.0
    # weights count: doubling the weight of the particles above 60 moves the mode up
    w2 = np.where(r > 60.0, 20.0, 1.0)
    assert most_probable_rul(r, w2 / w2.sum()) > mode
    # most of the mass beyond the horizon: the most probable outcome is no failure in sight
    r_inf = np.where(np.arange(r.size) < 0.6 * r.size, np.inf, r)
    assert most_probable_rul(r_inf, w) == np.inf
    # a degenerate cloud: its one value
    assert most_probable_rul(np.full(10, 7.0), np.full(10, 0.1)) == pytest.approx(7.0)


def test_rul_distribution_carries_its_mode_through_json() -> None:
    cfg = _config()
    pf = ParticleFilterPrognoser(cfg, MODEL)
    state = ParticleFilterPrognoser.initial_state(cfg, MODEL, rng_seed=3)
    truth = _truth("lin", 200)
    for k in range(0, 80, 2):
        state = pf.update(state, float(MODEL.predict(np.array([truth[k]]))[0]), k)
    dist = pf.predict(state)
    assert np.isfinite(dist.most_probable)
    assert dist.quantiles[0.05] <= dist.most_probable <= dist.quantiles[0.95]
    back = RulDistribution.from_json(dist.to_json())
    assert back.most_probable == pytest.approx(dist.most_probable)
    # documents written before the field existed still load
    old = json.loads(dist.to_json())
    del old["most_probable"]
    assert np.isnan(RulDistribution.from_dict(old).most_probable)


# -- degradation laws ----------------------------------------------------------------------------

H_GRID = np.linspace(0.0, 1.4, 15)


@pytest.mark.parametrize(
    ("law", "theta", "closed_form"),
    [
        (ConstantLaw(), (0.003,), lambda h: 0.003 + 0.0 * h),
        (AffineLaw(), (0.003, 0.002), lambda h: 0.003 + 0.002 * h),
        (QuadraticLaw(), (0.003, -0.001, 0.004), lambda h: 0.003 - 0.001 * h + 0.004 * h**2),
    ],
)
def test_polynomial_laws_match_their_closed_forms(law, theta, closed_form) -> None:  # noqa: ANN001
    """g(h) = theta . [1, h, h^2, ...] floored at min_rate; phi(h) the powers of h; the first
    trial is a constant rate; the RLS prior is rls_initial_cov I and s2 = q^2; the RLS measures
    the increment of the filtered severity against phi at the previous estimate."""
    theta = np.array(theta)
    p = theta.size
    assert law.n_params == p and isinstance(law, DegradationLaw)
    g = closed_form(H_GRID)
    np.testing.assert_allclose(law.growth_rate(H_GRID, theta, 1e-9), np.maximum(g, 1e-9),
                               rtol=1e-13)
    np.testing.assert_allclose(law.growth_rate(H_GRID, -theta, 1e-4), 1e-4)  # never heals
    phi = law.regressor(H_GRID)
    assert phi.shape == (H_GRID.size, p)
    np.testing.assert_allclose(phi, H_GRID[:, np.newaxis] ** np.arange(p), rtol=1e-15)
    np.testing.assert_allclose(phi @ theta, g, rtol=1e-13, atol=1e-18)
    assert law.coefficients(theta) is theta  # already the polynomial the prediction runs
    assert law.first_trial(0.004) == (0.004,) + (0.0,) * (p - 1)
    cfg = _config(rate_basis=law.rate_basis, rls_initial_cov=0.3)
    cov, s2 = law.prior(cfg)
    np.testing.assert_array_equal(cov, 0.3 * np.eye(p))
    assert s2 == cfg.process_noise_std**2
    state = ParticleFilterPrognoser.initial_state(cfg, MODEL, 0)
    state = replace(state, last_estimate=0.4, flight_index=10)
    step = law.rls_measurement(state, 0.43, 1.0, 3.0, MODEL, cfg)
    np.testing.assert_allclose(step.phi, 0.4 ** np.arange(p))
    assert step.y == pytest.approx(0.01) and step.forgetting == cfg.rls_forgetting
    assert step.theta is state.theta and step.cov is state.cov


@pytest.mark.parametrize(("offset", "rate"), [(0.1, 0.01), (1.78, 0.002), (-1.5, -0.004)])
def test_exponential_law_matches_its_closed_form(offset: float, rate: float) -> None:
    """dh/dk = r (h + c) whatever the intercept a of theta = (a, r); first trial r giving the
    initial rate at mid-life; prior diag(1, (0.35 r)^2), s2 = 1; the first measurement sets
    a = ln|h + c| with its whitened variance; the RLS measures the log-level whitened by its
    noise, with the intercept moved to the new flight and forgetting lambda ** dk."""
    law = ExponentialLaw(offset)
    assert law.n_params == 2 and isinstance(law, DegradationLaw)
    h = H_GRID[H_GRID + offset > 0] if offset > 0 else H_GRID[H_GRID < 1.3]
    for a in (0.0, -1.7):
        theta = np.array([a, rate])
        g = rate * (h + offset)
        np.testing.assert_allclose(law.growth_rate(h, theta, 1e-9), np.maximum(g, 1e-9),
                                   rtol=1e-12)
        np.testing.assert_allclose(law.regressor(h) @ theta, g, rtol=1e-12)
        np.testing.assert_allclose(law.coefficients(theta), [rate * offset, rate])
    first = law.first_trial(0.004)
    assert first[0] == 0.0 and first[1] * (0.5 + offset) == pytest.approx(0.004)
    cfg = _config(rate_basis="exponential", growth_offset=offset, initial_theta=(0.0, rate),
                  rls_forgetting=0.99)
    assert cfg.law == law
    cov, s2 = law.prior(cfg)
    np.testing.assert_allclose(cov, np.diag([1.0, (CONSTANTS.rate_prior_spread * rate) ** 2]))
    assert s2 == 1.0
    theta0, cov0 = law.first_measurement(np.array(cfg.theta0), cov, 0.2, 0.01)
    assert theta0[0] == pytest.approx(math.log(abs(0.2 + offset))) and theta0[1] == rate
    assert cov0[0, 0] == pytest.approx((0.01 / abs(0.2 + offset)) ** 2)
    assert cov0[1, 1] == cov[1, 1] and cov0[0, 1] == 0.0
    ident = MeasurementModel.identity(0.02)
    state = ParticleFilterPrognoser.initial_state(cfg, ident, 0)
    state = replace(state, theta=theta0, cov=cov0, last_estimate=0.2, flight_index=4)
    step = law.rls_measurement(state, 0.25, 0.26, 2.0, ident, cfg)
    sigma_y = 0.02 / abs(0.25 + offset)
    y = math.log(abs(0.25 + offset)) + 0.01 / (0.25 + offset)
    assert step.y == pytest.approx(y / sigma_y) and step.forgetting == pytest.approx(0.99**2)
    np.testing.assert_allclose(step.phi, [1.0 / sigma_y, 0.0])
    np.testing.assert_allclose(step.theta, [theta0[0] + 2.0 * rate, rate])


def test_law_registry_round_trips_through_the_rate_basis_string() -> None:
    """Every rate_basis a config accepts has one law class, found by its string; a config
    carries the string (never the class) through its JSON document, and gets the same law
    back."""
    assert tuple(LAWS) == typing.get_args(RateBasis)
    assert RATE_BASES == {name: law.n_params for name, law in LAWS.items()}
    for name, law_class in LAWS.items():
        assert law_for(name) is law_class and law_class.rate_basis == name
        n = law_class.n_params
        cfg = _config(rate_basis=name, initial_theta=(0.002,) * n, growth_offset=0.3)
        doc = json.loads(cfg.to_json())
        assert doc["rate_basis"] == name
        back = PrognoserConfig.from_dict(doc)
        assert back == cfg and type(back.law) is law_class and back.law == cfg.law
        assert back.n_params == n and len(back.theta0) == n
    with pytest.raises(ValueError, match="rate_basis must be one of"):
        law_for("cubic")
    with pytest.raises(ValueError, match="rate_basis must be one of"):
        _config(rate_basis="cubic")


#: prognoser configs as the trained chain wrote them into a model document before the law
#: classes existed (quick design campaign, seed 1: TTS on the log-level law, REWEAR affine),
#: with the digest the original code gave each with its measurement model
_TRAINED_DOCS = [
    ({"growth_offset": 0.0446683592150963, "histogram_bins": 30, "initial_rate": 0.004,
      "initial_rate_std": 0.0047720082559336114, "initial_severity_max": 0.5,
      "initial_theta": [0.0, 0.008427281127962228], "kind": "pf_prognoser_config",
      "max_horizon_flights": 2000, "min_rate": 1e-05, "monotone_rate": True,
      "n_particles": 200, "param_uncertainty_scale": 1.0, "pof_horizons_flights": [10, 25, 50],
      "prediction_steps": 50, "process_noise_std": 0.01,
      "quantile_levels": [0.05, 0.25, 0.5, 0.75, 0.95], "rate_basis": "exponential",
      "rate_bounds": [0.0024685309962371184, 0.010001247892871136], "resample_threshold": 0.5,
      "rls_forgetting": 0.995, "rls_initial_cov": 1.0, "rls_max_trace": 10.0, "version": 1},
     {"coefficients": [-0.0003957715108091411, 0.04861892770474073, -0.0010315702147371834],
      "kind": "polynomial_gaussian", "noise_slope": 0.0014383669371459311,
      "noise_std": 0.0001911507090983998, "severity_range": [0.0, 1.5], "version": 2},
     ExponentialLaw, "0ddecfbcd9bab79a"),
    ({"growth_offset": 0.5, "histogram_bins": 30, "initial_rate": 0.004,
      "initial_rate_std": None, "initial_severity_max": 0.5,
      "initial_theta": [0.006133037658576505, -0.00490578850497065],
      "kind": "pf_prognoser_config", "max_horizon_flights": 2000,
      "min_rate": 0.0008234908780076694, "monotone_rate": False, "n_particles": 200,
      "param_uncertainty_scale": 1.0, "pof_horizons_flights": [10, 25, 50],
      "prediction_steps": 50, "process_noise_std": 0.01,
      "quantile_levels": [0.05, 0.25, 0.5, 0.75, 0.95], "rate_basis": "affine",
      "rate_bounds": [0.0017607996463761594, 0.00782480973511007], "resample_threshold": 0.5,
      "rls_forgetting": 0.97, "rls_initial_cov": 0.01, "rls_max_trace": 10.0, "version": 1},
     {"coefficients": [1.0205562884044828e-05, 0.00014363101074826802, -4.385715528880922e-05],
      "kind": "polynomial_gaussian", "noise_slope": 1.5687965329507808e-05,
      "noise_std": 1.1517599103408967e-05, "severity_range": [0.0, 1.5], "version": 2},
     AffineLaw, "e619053f169a3d87"),
]


@pytest.mark.parametrize(("doc", "model", "law_class", "digest"), _TRAINED_DOCS)
def test_trained_model_documents_load_and_keep_their_digest(doc, model, law_class,  # noqa: ANN001
                                                            digest: str) -> None:
    """A config from an existing model document loads to its law, serialises back to the
    same text, and the filter's digest is unchanged (stored filter states still belong to
    their model)."""
    cfg = PrognoserConfig.from_dict(doc)
    assert type(cfg.law) is law_class
    assert cfg.to_json() == json.dumps(doc, sort_keys=True)
    pf = ParticleFilterPrognoser(cfg, MeasurementModel.from_dict(model))
    assert pf.digest == digest
    state = pf.initial_state(cfg, pf.measurement_model, 1)
    assert state.config_digest == digest


def test_first_version_config_document_loads() -> None:
    """A config document of the first version (no growth_offset, initial_rate_std or
    rate_bounds yet) loads with the defaults for them, and keeps the process noise it carries
    (every document carries one: a change of the default cannot reach it)."""
    old = {"version": 1, "kind": "pf_prognoser_config", "n_particles": 200,
           "process_noise_std": 0.004, "rate_basis": "affine", "initial_theta": None,
           "initial_rate": 0.004, "rls_forgetting": 0.97, "rls_initial_cov": 1.0,
           "rls_max_trace": 10.0, "min_rate": 1e-05, "resample_threshold": 0.5,
           "initial_severity_max": 0.5, "max_horizon_flights": 2000, "prediction_steps": 50,
           "param_uncertainty_scale": 1.0, "monotone_rate": True,
           "quantile_levels": [0.05, 0.25, 0.5, 0.75, 0.95], "pof_horizons_flights": [10, 25, 50],
           "histogram_bins": 30}
    cfg = PrognoserConfig.from_dict(old)
    assert type(cfg.law) is AffineLaw and cfg.theta0 == (0.004, 0.0)
    assert cfg.process_noise_std == 0.004 != PrognoserConfig().process_noise_std
    assert cfg.growth_offset == 0.5 and cfg.rate_bounds is None and cfg.initial_rate_std is None
    assert cfg == GENERIC_CONFIG


def test_config_defaults_are_the_chain_and_the_synthetic_series_values() -> None:
    """One owner per value: the config's default is the trained chain's process noise, the
    filter's synthetic series keep the one they were measured with."""
    assert PrognoserConfig().process_noise_std == 0.01
    assert GENERIC_CONFIG.process_noise_std == 0.004
    assert replace(GENERIC_CONFIG, process_noise_std=0.01) == PrognoserConfig()


def test_the_prediction_may_walk_with_its_own_noise_and_documents_without_it_are_unchanged(
        ) -> None:
    """``prediction_noise_std`` (None: the filter's process noise) drives the long-term
    prediction's random walk only: a config without it writes the same document, digest
    included, as before the field existed; with it, the filter's updates are unchanged and the
    RUL band narrows with a smaller walk."""
    base = _config(process_noise_std=0.02, param_uncertainty_scale=0.0)  # the walk alone
    assert "prediction_noise_std" not in base.to_dict()
    assert base.prediction_noise == base.process_noise_std
    quiet = replace(base, prediction_noise_std=1e-4)
    assert PrognoserConfig.from_json(quiet.to_json()) == quiet
    assert PrognoserConfig.from_json(base.to_json()) == base
    with pytest.raises(ValueError, match="prediction_noise_std"):
        replace(base, prediction_noise_std=0.0)
    widths = []
    for cfg in (base, quiet):
        pf = ParticleFilterPrognoser(cfg, MODEL)
        state = pf.initial_state(cfg, MODEL, 3)
        for k in range(1, 41):
            state = pf.update(state, float(MODEL.predict(np.array([0.01 * k]))[0]), k)
        dist = pf.predict(state)
        widths.append(dist.quantiles[0.95] - dist.quantiles[0.05])
        if cfg is base:
            first = state
        else:
            assert np.array_equal(state.severity, first.severity)
    assert widths[1] < 0.6 * widths[0], widths
