"""Training a model version from the quick design campaign: reproducible, leak-free, and a
model read back from JSON behaves exactly as the trained one."""

from __future__ import annotations

import json
import math

import pytest

from server.campaigns import load_campaign, train_from_directory
from server.phm.chain import PhmModel, analyze_flight
from server.phm.prognosis import PrognoserState
from tests.rate_bounds import assert_bounds_admit_the_bank

pytestmark = pytest.mark.slow


def test_same_campaign_and_seed_give_the_same_model_json(design_campaign_dir, trained_model
                                                        ) -> None:
    again, _ = train_from_directory(design_campaign_dir, seed=0, jobs=2)
    assert json.dumps(again.to_dict(), sort_keys=True) == json.dumps(trained_model[0],
                                                                     sort_keys=True)


def test_split_never_shares_a_degradation_pattern(trained_model) -> None:
    report = trained_model[1]["classifier"]
    train, test = set(report["train_groups"]), set(report["test_groups"])
    assert train and test and not train & test
    held_out_modes = {g.split("-")[1] for g in test}
    assert held_out_modes == {"TTS", "DMD", "SE", "BDO", "MTEL", "MTWEAR", "REWEAR"}


def test_model_from_json_analyses_flights_exactly_as_trained(design_campaign_dir,
                                                            trained_model) -> None:
    doc = trained_model[0]
    a, b = PhmModel.from_dict(doc), PhmModel.from_dict(json.loads(json.dumps(doc)))
    campaign = load_campaign(design_campaign_dir, jobs=2)
    pattern = next(p for p in campaign.patterns if p.mode == "TTS")
    ha = {pos: a.new_health(pos) for pos in ("WL1", "WL2", "WT")}
    hb = {pos: b.new_health(pos) for pos in ("WL1", "WL2", "WT")}
    for r in pattern.flights:
        oa = analyze_flight(a, r.features, ha, flight_index=r.index + 1)[pattern.position]
        ob = analyze_flight(b, r.features, hb, flight_index=r.index + 1)[pattern.position]
        assert oa.z == ob.z and oa.class_probabilities == ob.class_probabilities
        assert (oa.modes, oa.own_features) == (ob.modes, ob.own_features)
        assert (oa.rul is None) == (ob.rul is None)
        if oa.rul is not None:
            assert oa.rul.quantiles == ob.rul.quantiles
    assert oa.alarm and oa.fault_mode == "TTS" and oa.rul is not None
    assert a.crosstalk is not None and a.crosstalk == b.crosstalk  # fitted, read back
    # the filter starts at the alarm: the healthy flights before it are not fused
    health = ha[pattern.position]
    onset = int(pattern.onset_flight)
    assert health.alarm_index is not None and health.alarm_index > onset
    since_alarm = [r for r in pattern.flights if r.index + 1 >= health.alarm_index]
    state = PrognoserState.from_dict(health.prognosis)
    assert 1 <= state.n_updates <= len(since_alarm) <= len(pattern.flights) - onset


@pytest.mark.parametrize("old", ["ema-phm-model/1", "ema-phm-model/2", "ema-phm-model/3",
                                 "ema-phm-model/4"])
def test_a_model_of_an_older_chain_format_is_refused(trained_model, old: str) -> None:
    """A /1 model was trained on single-flight fleet residuals, a /2 model on the reversal
    lost motion as F_MTWEAR, a /3 model on the apparent-efficiency F_MTEL: they must be
    retrained, not silently misused."""
    doc = {**trained_model[0], "format": old}
    with pytest.raises(ValueError, match="hmsm train"):
        PhmModel.from_dict(doc)


def test_precise_wear_replays_its_filter_from_the_growth_onset(design_campaign_dir,
                                                               trained_model) -> None:
    """F_MTWEAR and the standby drive's rod-end play F_REWEAR resolve severity to hundredths:
    their filters are replayed from the estimated onset, so they fuse the flights between
    onset and alarm too; the thermal modes start at the alarm."""
    model = PhmModel.from_dict(trained_model[0])
    flags = {m: s.replay_from_onset for m, s in model.measurement.items()}
    assert flags == {"TTS": False, "DMD": False, "MTEL": False, "MTWEAR": True,
                     "REWEAR": True}
    assert model.measurement["MTWEAR"].prognoser.rate_basis == "exponential"
    campaign = load_campaign(design_campaign_dir, jobs=2)
    pattern = next(p for p in campaign.patterns if p.mode == "MTWEAR")
    health = {pos: model.new_health(pos) for pos in ("WL1", "WL2", "WT")}
    for r in pattern.flights:
        out = analyze_flight(model, r.features, health, flight_index=r.index + 1)
    own = health[pattern.position]
    assert out[pattern.position].fault_mode == "MTWEAR" and own.prognosis is not None
    feature = model.measurement["MTWEAR"].feature
    fused_since_alarm = sum(1 for i, z in own.history if i >= own.alarm_index and feature in z)
    state = PrognoserState.from_dict(own.prognosis)
    assert state.n_updates > fused_since_alarm


def test_measurement_noise_grows_with_severity_where_the_design_runs_show_it(
        trained_model) -> None:
    """On the design runs the scatter of F_TTS and F_MTWEAR around h(severity) at failure is
    several times that at the onset; the trained models carry it (sigma(1) / sigma(0))."""
    model = PhmModel.from_dict(trained_model[0])
    growth = {m: float(s.model.noise_at(1.0) / s.model.noise_at(0.0))
              for m, s in model.measurement.items()}
    assert growth["TTS"] > 2.0 and growth["MTWEAR"] > 2.0, growth
    assert all(g >= 1.0 for g in growth.values())


def test_winglet_wear_is_learned_as_it_grows(trained_model) -> None:
    """On the active-standby tab a worn drive keeps the load its role gives it, so its wear
    follows the mode's law, growing with its severity towards failure, with no partner taking
    the load: training learns one MTWEAR law per surface and both accelerate (the winglet's
    and the wingtip's), and REWEAR (all on the winglet) an accelerating exponential law."""
    model = PhmModel.from_dict(trained_model[0])
    mtwear = model.measurement["MTWEAR"]
    assert set(mtwear.prognoser_by_surface) == {"WL", "WT"}

    def late_over_early(c: float) -> float:  # dh/dk at h = 1 over dh/dk at onset
        return (1.0 + c) / (0.05 + c)

    wl = mtwear.config_for("WL1").growth_offset
    wt = mtwear.config_for("WT").growth_offset
    assert late_over_early(wl) > 1.0 and late_over_early(wt) > 1.0, (wl, wt)
    rewear = model.measurement["REWEAR"].config_for("WL2")
    assert rewear.rate_basis == "exponential", rewear.rate_basis
    assert late_over_early(rewear.growth_offset) > 1.0, rewear.growth_offset


def test_noise_free_features_feed_the_prognosis_the_true_severity(design_campaign_dir,
                                                                  trained_model) -> None:
    """The evaluation's error budget: with ``noise_free`` the faulty actuator's filter sees
    h(true severity) from the onset (and stores it in its history), so its severity estimate
    ends nearer the truth than with the measured feature on the flights that read it (a
    winglet drive's motor features are read on the flights it drives; in between, both runs
    propagate the same learned law); detection sees the real features, so the alarm flight
    does not move."""
    from server.evaluation.runner import run_pattern

    model = PhmModel.from_dict(trained_model[0])
    campaign = load_campaign(design_campaign_dir, jobs=2)
    pattern = next(p for p in campaign.patterns if p.mode == "DMD")
    spec = model.measurement["DMD"]

    name = f"{pattern.position}.{spec.feature}"
    read = {r.index for r in pattern.flights
            if math.isfinite(r.features.summaries[name].value)}

    def errors(trace):  # |estimated - true severity| where there is a RUL and a reading
        return [abs(f["rul"]["severity_mean"] - f["severity_norm"])
                for f in trace["flights"] if f["rul"] and f["index"] in read]

    real = run_pattern(model, pattern)
    free = run_pattern(model, pattern, noise_free=True)
    first = [next(f["index"] for f in t["flights"] if f["alarm"]) for t in (real, free)]
    assert first[0] == first[1]
    assert sum(errors(free)) < sum(errors(real))
    assert max(errors(free)[-3:]) < 0.05
    # the chain itself: the hook's values are what the actuator's history keeps
    health = {pos: model.new_health(pos) for pos in ("WL1", "WL2", "WT")}
    rec = pattern.flights[-1]
    analyze_flight(model, rec.features, health, flight_index=rec.index,
                   measurement_hook=lambda pos, v: {**v, spec.feature: 0.123}
                   if pos == pattern.position else v)
    assert health[str(pattern.position)].history[-1][1][spec.feature] == 0.123
    others = [p for p in health if p != pattern.position]
    assert all(health[p].history[-1][1].get(spec.feature) != 0.123 for p in others)


def test_the_rate_margins_set_how_far_a_filter_may_leave_the_design_rates(
        design_campaign_dir, trained_model) -> None:
    """Each mode's mid-life rate bounds are its slowest design run's rate over
    ``TrainingConfig.slow_rate_margin`` and its fastest run's times ``fast_rate_margin``:
    doubling the slow margin halves every lower bound, tripling the fast one triples every
    upper bound, and nothing else of the filter moves."""
    from dataclasses import replace

    from server.phm.training import TRAINING, train_phm_model

    campaign = load_campaign(design_campaign_dir, jobs=2)
    wide, report = train_phm_model(
        campaign, seed=0, training=replace(TRAINING, slow_rate_margin=2 * TRAINING.slow_rate_margin,
                                           fast_rate_margin=3 * TRAINING.fast_rate_margin))
    assert report["training"]["fast_rate_margin"] == 3 * TRAINING.fast_rate_margin
    base = PhmModel.from_dict(trained_model[0])
    for mode, spec in base.measurement.items():
        for position in ("WL1", "WT"):
            b, w = spec.config_for(position), wide.measurement[mode].config_for(position)
            assert w.rate_bounds[0] == pytest.approx(max(b.rate_bounds[0] / 2.0, 1e-5))
            assert w.rate_bounds[1] == pytest.approx(b.rate_bounds[1] * 3.0)
            assert replace(w, rate_bounds=b.rate_bounds, min_rate=b.min_rate) == b


@pytest.mark.parametrize("field,value", [("slow_rate_margin", 0.9),
                                         ("fast_rate_margin", float("nan")),
                                         ("rate_prior_inflation", 0.0),
                                         ("level_forgetting", 1.2),
                                         ("prior_weight_bounds", (1.0, 0.1)),
                                         ("rate_weighting", "vote")])
def test_training_constants_out_of_range_are_refused(field: str, value: object) -> None:
    from server.phm.training import TrainingConfig

    with pytest.raises(ValueError, match=field):
        TrainingConfig(**{field: value})


def test_training_can_learn_the_prediction_noise_from_the_design_runs(design_campaign_dir,
                                                                      trained_model) -> None:
    """With ``prediction_noise="design"`` every mode's prediction walks with its design runs'
    own flight-to-flight scatter about their fitted laws (the training report carries it as
    ``increment_noise``); by default the prediction keeps the filter's process noise and the
    model document does not name one."""
    from dataclasses import replace

    from server.phm.training import TRAINING, train_phm_model

    assert "prediction_noise_std" not in json.dumps(trained_model[0])
    campaign = load_campaign(design_campaign_dir, jobs=2)
    learned, report = train_phm_model(campaign, seed=0,
                                      training=replace(TRAINING, prediction_noise="design"))
    for mode, spec in learned.measurement.items():
        law = report["measurement"][mode]["degradation_prior"]
        for position in ("WL1", "WT"):
            cfg = spec.config_for(position)
            assert cfg.prediction_noise_std is not None and cfg.prediction_noise_std > 0, mode
            assert cfg.process_noise_std == PhmModel.from_dict(trained_model[0]).measurement[
                mode].config_for(position).process_noise_std
        assert cfg.prediction_noise_std in {law["increment_noise"]} | {
            s["increment_noise"] for s in law.get("by_surface", {}).values()}, mode


def test_training_with_rate_bands_gives_each_exponential_mode_a_bank_of_hypotheses(
        design_campaign_dir, trained_model) -> None:
    """With ``rate_band_edges`` (the default 30/100/300/1000) every mode tuned on the log-level
    gets one hypothesis per band, fastest first, its rates falling as the spans grow, and no
    tail mixture; the report carries them; the polynomial modes have none, nor does a model
    trained without bands (the tail mixture instead)."""
    from dataclasses import replace

    from server.phm.training import TRAINING, train_phm_model

    assert TRAINING.rate_band_edges == (30.0, 100.0, 300.0, 1000.0)
    campaign = load_campaign(design_campaign_dir, jobs=2)
    banked, report = train_phm_model(campaign, seed=0)
    assert json.dumps(banked.to_dict()["measurement"], sort_keys=True) == json.dumps(
        trained_model[0]["measurement"], sort_keys=True)
    plain, _ = train_phm_model(campaign, seed=0, training=replace(TRAINING, rate_band_edges=()))
    assert "rate_hypotheses" not in json.dumps(plain.to_dict())
    assert any(plain.measurement[m].config_for("WT").rate_prior_tail > 0
               for m in plain.measurement)
    exponential = 0
    for mode, spec in banked.measurement.items():
        for position in ("WL1", "WT"):
            cfg = spec.config_for(position)
            if cfg.rate_basis != "exponential":
                assert cfg.rate_hypotheses == (), mode
                continue
            exponential += 1
            bank = cfg.rate_hypotheses
            assert [h.name for h in bank] == ["fast", "medium", "slow"], mode
            assert cfg.rate_prior_tail == 0.0
            rates = [abs(h.rate) for h in bank]
            assert rates[0] > rates[1] > rates[2], mode
            assert_bounds_admit_the_bank(cfg, f"{mode} {position}")
        law = report["measurement"][mode]["degradation_prior"]
        if spec.config_for("WT").rate_basis == "exponential" and "hypotheses" in (law or {}):
            assert [h["name"] for h in law["hypotheses"]] == ["fast", "medium", "slow"]
    assert exponential > 0

