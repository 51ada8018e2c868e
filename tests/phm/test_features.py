"""Feature extraction: vectorised maths on synthetic d-q signals, and monotonicity on campaigns."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
from scipy.stats import spearmanr

import server.phm.features as features_module
import server.vocabulary as vocabulary
from server.phm.features import (
    ACTUATOR_FEATURES,
    AIRCRAFT_FEATURES,
    FeatureConfig,
    actuator_features,
    actuator_steps,
    block_mean,
    exp_filter,
    flight_features,
    rewear_feature,
    standby_play_feature,
)
from server.phm.features.numerics import row_max, row_min
from server.phm.features.steps import _cruise
from server.vocabulary import POSITIONS, SIGNALS

from .conftest import RS, make_actuator


def _feats(**kw: float) -> dict[str, float]:
    seed = int(kw.pop("seed", 1))
    sig = make_actuator(seed=seed, **kw)
    tracks, _ = actuator_features(sig, aero_gradient_n_per_m=4.0e4)
    return {k: t.value for k, t in tracks.items()}


def test_block_mean_and_exp_filter_match_loops() -> None:
    rng = np.random.default_rng(0)
    x = rng.standard_normal(1005)
    bm = block_mean(x, 10)
    assert bm.shape == (100,)
    assert np.allclose(bm, [x[10 * k:10 * k + 10].mean() for k in range(100)])
    a = 0.1
    y = exp_filter(bm, a)
    ref = np.empty_like(bm)
    prev = bm[0]
    for k, v in enumerate(bm):
        prev = a * v + (1 - a) * prev
        ref[k] = prev
    assert np.allclose(y, ref)
    two = exp_filter(np.c_[bm, 2 * bm], a)
    assert np.allclose(two[:, 1], 2 * ref)


def test_block_means_and_row_extremes_are_numpys_to_the_bit() -> None:
    """The column-wise block means and row extremes (a speed-up) give NumPy's own values."""
    rng = np.random.default_rng(1)
    for d in (*range(1, 21), 64):
        x = rng.standard_normal(3000 * d) * 10.0 ** rng.integers(-12, 12, 3000 * d)
        x[rng.random(x.size) < 0.05] = -0.0
        assert block_mean(x, d).tobytes() == x.reshape(-1, d).mean(axis=1).tobytes()
    assert block_mean(np.full(20, -0.0), 10).tobytes() == np.zeros(2).tobytes()
    special = np.array([0.0, -0.0, 1.0, -1.0, np.nan, np.inf, -np.inf])
    rows = np.array(np.meshgrid(special, special, special)).reshape(3, -1).T
    with np.errstate(invalid="ignore"):
        assert row_max(rows).tobytes() == rows.max(axis=1).tobytes()
        assert row_min(rows).tobytes() == rows.min(axis=1).tobytes()


def test_healthy_features_are_physical() -> None:
    f = _feats()
    assert abs(f["F_DMD"]) < 0.01  # flux estimate within 1 % of nominal
    assert f["F_SE"] < 0.005
    assert f["F_BDO"] < 0.03
    assert abs(f["F_MTWEAR"]) < 5e-6


def test_dmd_estimates_flux_loss() -> None:
    for h in (0.05, 0.1, 0.2):
        assert _feats(psi_scale=1 - h)["F_DMD"] == pytest.approx(h, abs=0.01)


def test_resistance_change_does_not_fake_magnet_loss() -> None:
    # a hot winding (higher R) is measured at still holds and removed from the power balance
    assert abs(_feats(r_ohm=2.3)["F_DMD"]) < 0.01


def test_se_measures_shaft_frequency_modulation() -> None:
    vals = [_feats(se_amp=e)["F_SE"] for e in (0.0, 0.02, 0.05)]
    assert vals[0] < 0.005
    assert vals[1] == pytest.approx(0.02, rel=0.3)
    assert vals[2] == pytest.approx(0.05, rel=0.2)


def test_tts_and_bdo_move_their_features() -> None:
    h = _feats()
    assert _feats(tts_i0=0.1)["F_TTS"] > 5 * h["F_TTS"]
    assert _feats(bdo=0.3)["F_BDO"] > 2 * h["F_BDO"]


def _friction_ratio(eta_d: float, eta_b: float, drag_nm: float, load_torque_nm: float) -> float:
    """Physics of F_MTEL: hysteresis W = |L| (1/eta_d - eta_b) + 2 T_c over T_ref + mean torque."""
    width = load_torque_nm * (1 / eta_d - eta_b) + 2 * drag_nm
    mean = load_torque_nm * (1 / eta_d + eta_b) / 2
    return width / (FeatureConfig().mtel_ref_torque_nm + mean)


def test_mtel_measures_screw_friction() -> None:
    """F_MTEL grows with the efficiency loss and with the drag of aged grease, as the torque
    hysteresis between upward and downward moves says (one-sided load, as at cruise)."""
    one_sided = {"load_gradient": 2.0e4, "load_bias_n": 1000.0}  # 600-1400 N
    cases = ((0.9, 0.89, 0.05), (0.85, 0.8, 0.08), (0.75, 0.67, 0.12))
    vals = [_feats(eta_d=d, eta_b=b, drag_nm=c, **one_sided)["F_MTEL"] for d, b, c in cases]
    assert vals[0] < vals[1] < vals[2]
    for (d, b, c), v in zip(cases, vals, strict=True):
        assert v == pytest.approx(_friction_ratio(d, b, c, RS * 1000.0), rel=0.1)
    # drag alone (grease) and efficiency alone (friction angle) both raise it
    assert _feats(drag_nm=0.1, **one_sided)["F_MTEL"] > vals[0] * 1.2
    assert _feats(eta_d=0.8, eta_b=0.75, drag_nm=0.05, **one_sided)["F_MTEL"] > vals[0] * 1.2


def test_mtel_ignores_the_load_level_on_a_healthy_drive() -> None:
    """With the healthy drag near T_ref k0 / 2, a flight at twice the dynamic pressure (load)
    gives the same value: the flight's unknown load scale does not fake aging."""
    k0 = (1 / 0.9 - 0.89) / ((1 / 0.9 + 0.89) / 2)
    drag = FeatureConfig().mtel_ref_torque_nm * k0 / 2
    low = _feats(drag_nm=drag, load_gradient=2.0e4, load_bias_n=1000.0)["F_MTEL"]
    high = _feats(drag_nm=drag, load_gradient=4.0e4, load_bias_n=2000.0)["F_MTEL"]
    assert low == pytest.approx(k0, rel=0.1)
    assert high == pytest.approx(low, rel=0.05)


def test_mtel_needs_a_load() -> None:
    """Under a load too light to carry the efficiency term there is no value."""
    assert np.isnan(_feats(drag_nm=0.05, load_gradient=0.0, load_bias_n=100.0)["F_MTEL"])


def test_mtel_counts_slow_steady_moves() -> None:
    """Moves 16 times slower (10-24 s each, as when a long flight stretches the reference
    cycle) still give the friction ratio of fast moves: F_MTEL counts steps from 1 Hz
    electrical; with the former 2 Hz too few steps were left for any value."""
    one_sided = {"load_gradient": 2.0e4, "load_bias_n": 1000.0, "drag_nm": 0.05, "seed": 3}
    fast = _feats(**one_sided)["F_MTEL"]
    slow_sig = make_actuator(move_time_scale=16.0, **one_sided)
    slow, _ = actuator_features(slow_sig, aero_gradient_n_per_m=4.0e4)
    assert slow["F_MTEL"].value == pytest.approx(fast, rel=0.03)
    old_cfg = replace(FeatureConfig(), mtel_min_electrical_hz=2.0)
    old, _ = actuator_features(slow_sig, aero_gradient_n_per_m=4.0e4, config=old_cfg)
    assert np.isnan(old["F_MTEL"].value)


def test_mtwear_grows_with_backlash() -> None:
    vals = [_feats(backlash_m=b)["F_MTWEAR"] for b in (0.0, 1e-4, 2e-4, 4e-4)]
    assert np.all(np.diff(vals) > 0)
    # the flank step is the gap itself, not a fraction of it
    assert vals == pytest.approx([0.0, 1e-4, 2e-4, 4e-4], abs=5e-6)


def test_mtwear_needs_both_flanks() -> None:
    """A flight whose load never changes sign keeps the screw on one flank: no gap value."""
    both = make_actuator(seed=2, backlash_m=2e-4)
    one_sided = make_actuator(seed=2, backlash_m=2e-4, load_bias_n=2000.0)
    assert np.isfinite(actuator_features(both, aero_gradient_n_per_m=4e4)[0]["F_MTWEAR"].value)
    tracks, _ = actuator_features(one_sided, aero_gradient_n_per_m=4e4)
    assert np.isnan(tracks["F_MTWEAR"].value)


def test_current_features_ignore_fast_windows() -> None:
    # a fast sweep whose electrical frequency exceeds 80 Hz contributes no current window
    n = 8000
    t = np.arange(n) / 800.0
    theta = 2 * np.pi * 25.0 * t  # 25 rev/s -> 100 Hz electrical
    sig = {k: np.zeros(n) for k in ("ia", "ib", "ic", "va", "vb", "vc")}
    sig["ia"] = 2 * np.cos(4 * theta)
    sig["ib"] = 2 * np.cos(4 * theta - 2 * np.pi / 3)
    sig["ic"] = 2 * np.cos(4 * theta + 2 * np.pi / 3)
    sig["va"], sig["vb"], sig["vc"] = 20 * sig["ia"], 20 * sig["ib"], 20 * sig["ic"]
    sig["theta"], sig["x"] = theta, RS * theta
    tracks, _ = actuator_features(sig, aero_gradient_n_per_m=4e4)
    for f in ("F_TTS", "F_DMD", "F_SE", "F_BDO"):
        assert tracks[f].n_valid == 0
        assert np.isnan(tracks[f].value)


def test_rewear_sees_lost_motion_between_winglet_rods() -> None:
    a = make_actuator(seed=3)
    # the rod end's gap is crossed at reversals when its load follows the motion
    b = make_actuator(seed=3, backlash_m=3e-4, backlash_follows="motion")
    c = make_actuator(seed=3, backlash_m=6e-4, backlash_follows="motion")
    base = rewear_feature(a["x"], a["x"], a["theta"], a["theta"]).value
    v1 = rewear_feature(a["x"], b["x"], a["theta"], b["theta"]).value
    v2 = rewear_feature(a["x"], c["x"], a["theta"], c["theta"]).value
    assert base < 2e-5 < v1 < v2


def _three_drives(seconds: float = 30.0) -> dict[str, np.ndarray]:
    ch: dict[str, np.ndarray] = {}
    for i, p in enumerate(("WL1", "WL2", "WT")):
        sig = make_actuator(seed=10 + i, seconds=seconds)
        for k, v in sig.items():
            if k != "t":
                ch[f"{p}.{k}"] = v
        ch["t"] = sig["t"]
    ch["T_amb"] = np.linspace(15.0, -40.0, ch["t"].size)
    return ch


def test_a_standby_drive_carries_its_rod_end_play_and_no_motor_feature() -> None:
    """WL2 stands by: its six motor features are not read (NaN, no valid step), its rod-end
    play is; the active WL1 carries its six and no play; WT is untouched by the roles."""
    ch = _three_drives()
    both = flight_features(ch)
    roles = flight_features(ch, active_channels=("WL1", "WT"), keep_tracks=True)
    assert tuple(roles.summaries) == AIRCRAFT_FEATURES
    def same(a: str, b: str = "") -> bool:  # NaN-equal
        x, y = roles.summaries[a], both.summaries[b or a]
        return np.array_equal([x.value, x.dispersion, x.n_valid],
                              [y.value, y.dispersion, y.n_valid], equal_nan=True)

    for g in ACTUATOR_FEATURES:
        assert np.isnan(roles.summaries[f"WL2.{g}"].value)
        assert roles.summaries[f"WL2.{g}"].n_valid == 0
        assert same(f"WL1.{g}") and same(f"WT.{g}")
    assert np.isnan(roles.summaries["WL1.F_REWEAR"].value)
    assert roles.tracks is not None and "WL1.F_REWEAR" not in roles.tracks
    play = standby_play_feature(ch["WL1.x"], ch["WL2.x"], ch["WL1.theta"], ch["WL2.theta"],
                                actuator_steps({s: ch[f"WL1.{s}"] for s in SIGNALS}).i_q)
    assert np.array_equal(roles.tracks["WL2.F_REWEAR"].series, play.series, equal_nan=True)
    # both active (no roles named, or every drive named): the pair's lost motion on both
    assert both.summaries["WL1.F_REWEAR"] == both.summaries["WL2.F_REWEAR"]
    named = flight_features(ch, active_channels=POSITIONS)
    assert json.dumps(named.to_dict()) == json.dumps(both.to_dict())
    assert np.isnan(roles.conditions["WL2"]["temp_winding_est_c"])
    assert roles.conditions["WL2"]["load_rms_n"] == both.conditions["WL2"]["load_rms_n"]
    with pytest.raises(ValueError, match="no winglet drive"):
        flight_features(ch, active_channels=("WT",))


def test_flight_features_gives_twenty_with_conditions() -> None:
    ch = _three_drives()
    ff = flight_features(ch, keep_tracks=True)
    assert tuple(ff.summaries) == AIRCRAFT_FEATURES and len(AIRCRAFT_FEATURES) == 20
    assert ff.conditions["WT"]["temp_ground_c"] == pytest.approx(15.0)
    assert ff.tracks is not None and ff.tracks["WT.F_DMD"].series.size == ch["t"].size // 10
    for name, s in ff.summaries.items():
        if not name.endswith("F_MTEL"):  # MTEL is cruise-gated by T_amb
            assert s.n_valid > 0, name


@pytest.mark.parametrize("offset_k", [0.0, 5.0, 15.0, -15.0])
def test_cruise_is_the_flight_s_coldest_air_whatever_the_day(offset_k: float) -> None:
    """F_MTEL's cruise window follows the air: the same steps on a day 5 or 15 K warmer or
    15 K colder (a fixed -37 degC threshold found none above +3 K and took in the climb at
    -15 K); a run that never climbed has none."""
    t = np.linspace(0.0, 1.0, 1000)
    alt = np.clip(np.minimum(t, 1.0 - t) / 0.2, 0.0, 1.0)  # climb, cruise, descent
    air = 15.0 + (-40.0 - 15.0) * alt  # ground to the design cruise air
    cfg = FeatureConfig()
    nominal = _cruise(air, cfg)
    assert nominal.sum() == np.count_nonzero(air <= -37.0) > 0
    assert np.array_equal(_cruise(air + offset_k, cfg), nominal)
    assert not _cruise(np.full(1000, 15.0 + offset_k), cfg).any()


def test_config_validation() -> None:
    with pytest.raises(ValueError):
        FeatureConfig(decimation=0)


# --------------------------------------------------------------------------------------------
# on simulated campaigns
# --------------------------------------------------------------------------------------------

OWN_FEATURE = {m: vocabulary.OWN_FEATURE[m] for m in vocabulary.PROGRESSIVE}


@pytest.mark.slow
@pytest.mark.parametrize("mode", sorted(OWN_FEATURE))
def test_each_feature_is_monotone_with_its_fault(mode: str, design_campaign) -> None:
    pats = [p for p in design_campaign.patterns if p.mode == mode]
    if not pats:
        pytest.skip(f"no {mode} pattern in the design campaign")
    rhos = []
    for p in pats:
        name = f"{p.position}.{OWN_FEATURE[mode]}"
        sev = np.array([r.severity for r in p.flights])
        val = np.array([r.features.summaries[name].value for r in p.flights])
        ok = np.isfinite(val)
        rho = spearmanr(sev[ok], val[ok]).statistic
        rhos.append(abs(rho))
    assert np.median(rhos) >= 0.6, rhos


def test_feature_names_cover_table_1() -> None:
    assert set(ACTUATOR_FEATURES) == {"F_TTS", "F_DMD", "F_SE", "F_BDO", "F_MTEL", "F_MTWEAR"}


def test_vocabulary_names_are_re_exported() -> None:
    """The names the vocabulary owns are the same objects under server.phm.features."""
    for name in ("ACTUATOR_FEATURES", "POSITIONS", "WINGLET_PAIR"):
        assert getattr(features_module, name) is getattr(vocabulary, name)
        assert name in features_module.__all__
