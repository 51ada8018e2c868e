"""The bank of rate hypotheses (``PrognoserConfig.rate_hypotheses``): bands of fault-to-failure
spans, each with its rate prior, weighed by the measurements."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from server.phm.prognosis import (
    GENERIC_CONFIG,
    MeasurementModel,
    ParticleFilterPrognoser,
    PrognoserConfig,
    RulDistribution,
)
from server.phm.prognosis.calibration import CalibrationRecord, fit_band_calibration
from server.phm.prognosis.hypotheses import (
    RateHypothesis,
    band_names,
    fit_rate_hypotheses,
    leading_hypothesis,
)

MODEL = MeasurementModel((0.2, 2.0, 0.5), 0.03)  # feature = 0.2 + 2 h + 0.5 h^2 + N(0, 0.03^2)
OFFSET = 0.1
H0 = 0.15  # severity at the first measurement (an alarm)
RHO = math.log((1.0 + OFFSET) / (H0 + OFFSET))  # rate x span of every run of this law
EDGES = (30.0, 100.0, 300.0, 1000.0)


def _rate(life: float) -> float:
    return RHO / life


def _design_spans(n: int, seed: int) -> np.ndarray:
    """A design's spans, log-uniform over the envelope (as the design campaigns draw them)."""
    return np.exp(np.random.default_rng(seed).uniform(math.log(30), math.log(1000), n))


def _bank(n_runs: int = 10, seed: int = 0) -> tuple[RateHypothesis, ...]:
    spans = _design_spans(n_runs, seed)
    return fit_rate_hypotheses(RHO / spans, spans, band_names(EDGES))


#: one normal prior over the whole envelope (what a single design prior gives), and the bank
WIDE = replace(GENERIC_CONFIG, rate_basis="exponential", growth_offset=OFFSET,
               initial_theta=(0.0, _rate(175)), initial_rate_std=1.2 * _rate(175),
               rls_forgetting=0.995, process_noise_std=0.01)
BANK = replace(WIDE, rate_hypotheses=_bank())


def _series(life: int, seed: int) -> np.ndarray:
    k = np.arange(life + 1, dtype=float)
    h = (H0 + OFFSET) * np.exp(_rate(life) * k) - OFFSET
    return MODEL.predict(h) + MODEL.noise_std * np.random.default_rng(seed).standard_normal(
        k.size)


def _predictions(cfg: PrognoserConfig, life: int, seed: int, every: int = 5
                 ) -> list[tuple[int, RulDistribution]]:
    """(true RUL, prediction) from a fifth of the life on, every ``every`` flights."""
    z = _series(life, seed)
    pf = ParticleFilterPrognoser(cfg, MODEL)
    state = pf.initial_state(cfg, MODEL, seed)
    out = []
    for k in range(life - 2):
        state = pf.update(state, float(z[k]), k)
        if k >= life // 5 and k % every == 0:
            out.append((life - k, pf.predict(state)))
    return out


def test_bands_are_named_fastest_first_and_bad_edges_are_refused() -> None:
    assert band_names(EDGES) == (("fast", 30.0, 100.0), ("medium", 100.0, 300.0),
                                 ("slow", 300.0, 1000.0))
    assert band_names(()) == ()
    for bad in ((100.0,), (100.0, 30.0), (0.0, 10.0), (1.0, math.inf), tuple(range(1, 9))):
        with pytest.raises(ValueError, match="edges"):
            band_names(bad)


def test_each_band_takes_the_moments_of_rho_over_its_spans() -> None:
    """Runs sharing one rho: each band's mean is rho E[1/span] over the band, its sd the
    spread of 1/span there; a band without a design run of its own is still informed."""
    spans = np.array([40.0, 50.0, 500.0, 800.0])  # no run in 100-300
    bank = fit_rate_hypotheses(RHO / spans, spans, band_names(EDGES))
    for h in bank:
        a, b = h.low_flights, h.high_flights
        inv1 = (1 / a - 1 / b) / math.log(b / a)
        inv2 = (1 / a**2 - 1 / b**2) / (2 * math.log(b / a))
        assert h.rate == pytest.approx(RHO * inv1)
        assert h.rate_std == pytest.approx(RHO * math.sqrt(inv2 - inv1**2))
        assert h.weight == pytest.approx(1 / 3)
    assert [h.spans for h in bank] == ["30-100 flights", "100-300 flights", "300-1000 flights"]
    with pytest.raises(ValueError, match="two runs"):
        fit_rate_hypotheses([0.01], [100.0], band_names(EDGES))


def test_a_fast_fault_is_named_fast_and_its_band_holds_it() -> None:
    """A 50-flight life: after 15 flights the fast hypothesis leads with most of the weight,
    the prediction names it, and the 90 % bands hold the truth where the single wide prior's
    are late to follow."""
    z = _series(50, seed=1)
    pf = ParticleFilterPrognoser(BANK, MODEL)
    state = pf.initial_state(BANK, MODEL, 5)
    for k in range(15):
        state = pf.update(state, float(z[k]), k)
    lead = pf.predict(state).hypothesis
    assert lead is not None and lead["name"] == "fast" and lead["weight"] > 0.8
    assert lead["spans"] == "30-100 flights"
    assert sum(lead["weights"].values()) == pytest.approx(1.0)
    hits = [p.quantile(0.05) <= t <= p.quantile(0.95)
            for seed in range(3) for t, p in _predictions(BANK, 50, seed, every=3)]
    assert np.mean(hits) >= 0.85


def test_in_range_the_medium_hypothesis_leads_and_predicts_as_well_as_one_wide_prior() -> None:
    """A 200-flight life: the medium hypothesis leads; the bank's medians are as close to the
    truth as the wide prior's and its 90 % bands hold it. (On this precise synthetic feature
    the rate is learnt within a few flights whatever the prior, so the bands' widths agree;
    what the bank changes on the chain's noisier features is measured on campaigns.)"""
    bank = [(t, p) for seed in range(3) for t, p in _predictions(BANK, 200, seed, every=10)]
    wide = [(t, p) for seed in range(3) for t, p in _predictions(WIDE, 200, seed, every=10)]
    assert bank[-1][1].hypothesis is not None and bank[-1][1].hypothesis["name"] == "medium"

    def error(preds: list[tuple[int, RulDistribution]]) -> float:
        return float(np.median([abs(p.median - t) / t for t, p in preds]))

    assert error(bank) <= error(wide) + 0.02
    assert np.mean([p.quantile(0.05) <= t <= p.quantile(0.95) for t, p in bank]) >= 0.9
    assert all(p.hypothesis is None for _, p in wide)


def test_the_bank_round_trips_and_is_validated() -> None:
    assert "rate_hypotheses" not in WIDE.to_dict()
    again = PrognoserConfig.from_json(BANK.to_json())
    assert again == BANK and again.rate_hypotheses == BANK.rate_hypotheses
    assert ParticleFilterPrognoser(BANK, MODEL).digest != ParticleFilterPrognoser(WIDE,
                                                                                  MODEL).digest
    with pytest.raises(ValueError, match="rate_prior_tail"):
        replace(BANK, rate_prior_tail=0.2)
    with pytest.raises(ValueError, match="exponential"):
        replace(GENERIC_CONFIG, rate_hypotheses=BANK.rate_hypotheses)
    with pytest.raises(ValueError, match="distinct"):
        replace(BANK, rate_hypotheses=BANK.rate_hypotheses[:1] * 2)
    with pytest.raises(ValueError, match="sign"):
        replace(BANK, rate_hypotheses=(replace(BANK.rate_hypotheses[0], rate=-0.01),))
    with pytest.raises(ValueError, match="weight"):
        RateHypothesis("fast", 30, 100, 0.01, 0.001, 0.0)


def test_the_prediction_carries_its_leading_hypothesis_through_its_document() -> None:
    _, dist = _predictions(BANK, 60, seed=2)[-1]
    again = RulDistribution.from_json(dist.to_json())
    assert again.hypothesis == dist.hypothesis
    assert leading_hypothesis(BANK.rate_hypotheses, np.array([0.1, 0.7, 0.2]))["name"] == \
        "medium"


def test_the_calibration_layer_groups_by_leading_hypothesis() -> None:
    """Each hypothesis gets its own margins; a prediction without one takes the pooled."""
    rng = np.random.default_rng(4)
    records = []
    for name, bias in (("fast", 0.5), ("medium", 0.0), ("slow", -0.3)):
        for _ in range(60):
            y = float(rng.uniform(20, 200))
            centre = y * math.exp(bias + 0.1 * rng.standard_normal())
            records.append(CalibrationRecord({0.05: 0.7 * centre, 0.25: 0.9 * centre,
                                              0.5: centre, 0.75: 1.1 * centre,
                                              0.95: 1.3 * centre}, math.nan, y, name))
    layer = fit_band_calibration(records, min_group=30, hypotheses=("fast", "medium", "slow"))
    assert layer.counts == (60, 60, 60) and layer.edges == ()
    assert layer.shifts[0] < -0.3 < 0.2 < layer.shifts[2]  # optimistic fast, cautious slow
    assert layer.margins_for(math.nan, "fast")[0] == 0
    assert layer.margins_for(1.0, None)[0] == -1
    assert type(layer).from_dict(layer.to_dict()) == layer


def _record(rng: np.random.Generator, name: str, weight: float, bias: float
            ) -> CalibrationRecord:
    """A prediction led by ``name`` with ``weight``, its band 0.7-1.3 x a centre off the
    truth by ``bias`` in log."""
    y = float(rng.uniform(20, 200))
    centre = y * math.exp(bias + 0.1 * rng.standard_normal())
    return CalibrationRecord({0.05: 0.7 * centre, 0.25: 0.9 * centre, 0.5: centre,
                              0.75: 1.1 * centre, 0.95: 1.3 * centre}, math.nan, y, name,
                             weight)


def test_the_layer_calibrates_an_ambiguous_lead_apart_from_a_confident_one() -> None:
    """Optimistic ambiguous leads (a fast life still led by a slower band) get their own,
    wider lower margin; a split group too small for its own takes its hypothesis's."""
    rng = np.random.default_rng(5)
    records = ([_record(rng, "medium", 0.55, 0.6) for _ in range(40)]
               + [_record(rng, "medium", 0.97, 0.0) for _ in range(120)]
               + [_record(rng, "fast", 0.6, 0.6) for _ in range(10)]
               + [_record(rng, "fast", 0.99, 0.0) for _ in range(60)])
    names = ("fast", "medium", "slow")
    layer = fit_band_calibration(records, min_group=30, hypotheses=names, weight_split=0.8)
    assert layer.split_counts == (10, 60, 40, 120, 0, 0)
    ambiguous = layer.margins_for(math.nan, "medium", 0.55)
    confident = layer.margins_for(math.nan, "medium", 0.97)
    assert ambiguous[0] == confident[0] == 1
    assert ambiguous[1][0.9][0] > confident[1][0.9][0] + 0.3  # the lower end moves down
    assert ambiguous[2] < confident[2] - 0.3  # and the median with it
    unsplit = fit_band_calibration(records, min_group=30, hypotheses=names)
    assert layer.margins_for(math.nan, "fast", 0.6)[1] == unsplit.margins_for(math.nan,
                                                                               "fast")[1]
    assert type(layer).from_dict(layer.to_dict()) == layer
    assert "weight_split" not in unsplit.to_dict()
    with pytest.raises(ValueError, match="weight_split"):
        fit_band_calibration(records, hypotheses=names, weight_split=1.5)


EVIDENCE = replace(BANK, rate_weighting="evidence")


def test_without_forgetting_the_evidence_is_the_product_of_the_predictive_likelihoods() -> None:
    """With no forgetting the bands' evidence and the product of each RLS's predictive
    likelihoods are the same number (the Kalman filter's prediction-error decomposition):
    the two weightings agree to rounding, and part ways only where the RLS forgets."""
    exact = {w: replace(BANK, rate_weighting=w, rls_forgetting=1.0, rls_max_trace=1e12)
             for w in ("predictive", "evidence")}
    z = _series(150, seed=3)
    weights = {}
    for w, cfg in exact.items():
        pf = ParticleFilterPrognoser(cfg, MODEL)
        state = pf.initial_state(cfg, MODEL, 5)
        for k in range(40):
            state = pf.update(state, float(z[k]), 2 * k)  # every other flight: dk = 2
        assert state.mixture is not None
        weights[w] = state.mixture.log_weights
    np.testing.assert_allclose(weights["evidence"], weights["predictive"], atol=1e-6)


def test_the_evidence_names_the_band_the_rate_lies_in_when_the_law_is_misfit() -> None:
    """A life that accelerates beyond the law (its rate doubles over the life, as a wear
    fault's does when its clearance opens): the predictive weights drift towards the fast
    band, whose wide prior follows the misfit best (0.04 at 40 flights, 0.17 at 160), while
    the evidence keeps the medium band, whose prior holds the rate the measurements show."""
    life = 200
    k = np.arange(life + 1, dtype=float)
    r = _rate(life) * (0.7 + 0.6 * k / life)  # from 0.7x to 1.3x the mean rate
    h = (H0 + OFFSET) * np.exp(np.cumsum(np.r_[0.0, r[:-1]])) - OFFSET
    z = MODEL.predict(h) + 0.01 * np.random.default_rng(7).standard_normal(k.size)
    leads = {}
    for cfg in (BANK, EVIDENCE):
        pf = ParticleFilterPrognoser(cfg, MODEL)
        state = pf.initial_state(cfg, MODEL, 5)
        for i in range(int(0.8 * life)):
            state = pf.update(state, float(z[i]), i)
        lead = pf.predict(state).hypothesis
        assert lead is not None
        leads[cfg.rate_weighting] = lead
    assert leads["evidence"]["name"] == "medium"
    assert leads["evidence"]["weights"]["medium"] > 0.9
    assert leads["evidence"]["weights"]["fast"] < 0.5 * leads["predictive"]["weights"]["fast"]


def test_an_evidence_state_restores_and_the_weighting_is_validated() -> None:
    z = _series(80, seed=4)
    pf = ParticleFilterPrognoser(EVIDENCE, MODEL)
    state = pf.initial_state(EVIDENCE, MODEL, 5)
    for k in range(20):
        state = pf.update(state, float(z[k]), k)
    again = type(state).from_json(state.to_json())
    assert again.mixture is not None and again.mixture.evidence is not None
    a, b = pf.update(state, float(z[20]), 20), pf.update(again, float(z[20]), 20)
    assert a.mixture is not None and b.mixture is not None
    np.testing.assert_array_equal(a.mixture.log_weights, b.mixture.log_weights)
    assert "rate_weighting" not in BANK.to_dict()
    assert PrognoserConfig.from_json(EVIDENCE.to_json()) == EVIDENCE
    assert pf.digest != ParticleFilterPrognoser(BANK, MODEL).digest
    with pytest.raises(ValueError, match="rate_weighting"):
        replace(BANK, rate_weighting="vote")
    with pytest.raises(ValueError, match="needs rate_hypotheses"):
        replace(WIDE, rate_weighting="evidence")


def test_a_misfit_law_weakens_the_measurements_not_the_bands_priors() -> None:
    """Measurements six times noisier than the measurement model says (the RLS's residual
    variance about 6): a 70-flight life still leads "fast" (0.95), the band its rate lies in.
    Were the bands' priors scaled with that variance, as the RLS's own normalisation scales
    them, the narrower medium band would lead (0.64) by its Occam factor."""
    life = 70
    k = np.arange(life + 1, dtype=float)
    h = (H0 + OFFSET) * np.exp(_rate(life) * k) - OFFSET
    z = MODEL.predict(h) + 6 * MODEL.noise_std * np.random.default_rng(2).standard_normal(
        k.size)
    pf = ParticleFilterPrognoser(EVIDENCE, MODEL)
    state = pf.initial_state(EVIDENCE, MODEL, 5)
    for i in range(0, int(0.6 * life), 2):
        state = pf.update(state, float(z[i]), i)
    assert state.resid_var > 4.0
    lead = pf.predict(state).hypothesis
    assert lead is not None and lead["name"] == "fast" and lead["weight"] > 0.9
