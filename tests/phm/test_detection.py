"""Baselines and detection: unit tests on synthetic residuals, campaign tests on the simulator."""

from __future__ import annotations

import json

import numpy as np
import pytest

from server.evaluation.evaluate_detection import PatternOutcome, summarise
from server.phm.baselines import BASELINE_DEFAULTS, BaselineConfig, FleetBaseline, LinearBaseline
from server.phm.detection import (
    DETECTION_DEFAULTS,
    UNITS,
    DetectionConfig,
    DetectionState,
    FaultDetector,
    confidence_sequence,
    decide,
    new_state,
    observe,
    offset_components,
    partner_held,
    running_statistics,
    update_units,
)
from server.phm.detection_model import DetectionModel
from server.phm.features import AIRCRAFT_FEATURES, FeatureSummary, FlightFeatures
from tests.phm.judging import judge_alone


def test_linear_baseline_removes_temperature_and_load_trend() -> None:
    rng = np.random.default_rng(0)
    n = 400
    temp = rng.uniform(-10, 45, n)
    load = rng.uniform(200, 900, n)
    y = 1.0 + 0.02 * temp + 0.001 * load + 0.01 * rng.standard_normal(n)
    C = np.c_[temp, load]
    b = LinearBaseline(("temp_ground_c", "load_rms_n"), ridge=1e-6).fit(C, y)
    z = b.zscore(C, y)
    assert abs(np.mean(z)) < 0.1 and 0.8 < np.std(z) < 1.25
    # hot and cold flights share one distribution after normalisation
    assert abs(z[temp > 30].mean() - z[temp < 5].mean()) < 0.3
    b2 = LinearBaseline.from_dict(json.loads(json.dumps(b.to_dict())))
    assert np.allclose(b2.zscore(C, y), z)
    # missing covariates fall back to the training mean instead of NaN
    assert np.isfinite(b.predict(np.array([[np.nan, 500.0]]))).all()


def test_linear_baseline_is_robust_to_outliers() -> None:
    rng = np.random.default_rng(1)
    C = rng.uniform(0, 1, (200, 1))
    y = 2 * C[:, 0] + 0.05 * rng.standard_normal(200)
    y[:5] += 50.0
    b = LinearBaseline(("temp_ground_c",), ridge=1e-6).fit(C, y)
    assert b.scale_ == pytest.approx(0.05, rel=0.3)


def test_linear_baseline_learns_slopes_within_units() -> None:
    """Ten units whose offsets (8 flight-scatter units apart) happen to fall with their base's
    temperature: the pooled fit reads that as a slope, the within-unit fit finds the true one,
    and each unit's residual then stays flat through its seasons."""
    rng = np.random.default_rng(3)
    slope, scatter = 0.02, 0.1
    units, temps, values = [], [], []
    for g in range(10):
        base_temp = -5.0 + 3.5 * g  # colder to hotter bases
        offset = -0.08 * (base_temp - 10.0) + 0.1 * rng.standard_normal()
        t = base_temp + rng.uniform(-12, 12, 150)  # one unit's seasons
        units += [f"U{g}"] * t.size
        temps.append(t)
        values.append(offset + slope * t + scatter * rng.standard_normal(t.size))
    C, y = np.concatenate(temps)[:, None], np.concatenate(values)
    pooled = LinearBaseline(("temp_ground_c",), ridge=1e-6).fit(C, y)
    within = LinearBaseline(("temp_ground_c",), ridge=1e-6).fit(C, y, units)
    per_k = within.cov_scale_[0]  # the slope is on the standardised covariate
    assert within.coef_[0] / per_k == pytest.approx(slope, rel=0.1)
    assert abs(pooled.coef_[0] / per_k - slope) > 0.05  # the offsets' trend taken for a slope
    # a unit's residuals, cold against hot flights of its own: flat within its scatter
    u0 = np.array(units) == "U0"
    z = within.zscore(C[u0], y[u0])
    t0 = C[u0, 0]
    assert abs(z[t0 > np.median(t0)].mean() - z[t0 <= np.median(t0)].mean()) < 0.5 * np.std(z)
    with pytest.raises(ValueError, match="one label per flight"):
        LinearBaseline(("temp_ground_c",)).fit(C, y, units[:-1])


def test_unfitted_models_refuse() -> None:
    with pytest.raises(RuntimeError):
        LinearBaseline().predict(np.zeros((1, 4)))
    with pytest.raises(RuntimeError):
        new_state(FaultDetector(), "WT")


def _flight(rng: np.random.Generator, shift: dict[str, float] | None = None) -> FlightFeatures:
    shift = shift or {}
    summ = {n: FeatureSummary(float(rng.standard_normal() + shift.get(n, 0.0)), 0.1, 100)
            for n in AIRCRAFT_FEATURES}
    cond = {p: {"temp_ground_c": float(rng.uniform(-5, 40)), "temp_mean_c": 0.0,
                "load_rms_n": 500.0, "speed_rms_rad_s": 10.0, "temp_winding_est_c": 30.0}
            for p in ("WL1", "WL2", "WT")}
    return FlightFeatures(summ, cond)


def test_running_statistics_matches_naive_and_skips_nan() -> None:
    rng = np.random.default_rng(2)
    z = rng.standard_normal((30, 2))
    z[5, 0] = np.nan
    s = running_statistics(z, 3)
    col = z[:, 0]
    valid = [v for v in col if np.isfinite(v)]
    # flight 10 of column 0: last three valid values up to flight 10
    upto = [v for v in col[:11] if np.isfinite(v)]
    assert s[10, 0] == pytest.approx(sum(upto[-3:]) / np.sqrt(3))
    assert s[5, 0] == s[4, 0]  # held through the missing flight
    assert len(valid) == 29
    assert s[0, 1] == pytest.approx(z[0, 1])


def test_detector_quiet_on_healthy_and_fast_on_steps() -> None:
    rng = np.random.default_rng(3)
    names = ["WT.F_A", "WT.F_B"]
    train = [rng.standard_normal((300, 2)) for _ in range(8)]
    det = FaultDetector().fit(train, names)
    # fresh healthy sequences: no alarm
    for _ in range(10):
        conf = confidence_sequence(det, rng.standard_normal((300, 2)), names)
        assert conf.max() < det.alarm_confidence
    # a step of 12 standard deviations alarms on the first faulty flight
    st = DetectionState.new("WT", names)
    for k in range(20):
        z = {"WT.F_A": float(rng.standard_normal()), "WT.F_B": float(rng.standard_normal())}
        if k >= 10:
            z["WT.F_B"] += 12.0
        res = judge_alone(det, st, z)
        if k < 10:
            assert not res.alarm
    assert st.alarm and st.alarm_flight == 11 and st.alarm_features == ["WT.F_B"]
    # a slow drift alarms only once it has clearly left the band
    st2 = DetectionState.new("WT", names)
    first = None
    for k in range(200):
        z = {"WT.F_A": float(rng.standard_normal() + 0.03 * k), "WT.F_B": 0.0}
        if judge_alone(det, st2, z).new_alarm:
            first = k
    assert first is not None and 40 < first < 200


def _offset_population(rng: np.random.Generator, n_actuators: int, n_flights: int,
                       tau: float = 2.0, sigma: float = 0.3) -> list[np.ndarray]:
    """Actuator histories z = u + e of one feature: production offset u, flight scatter e."""
    return [rng.normal(rng.normal(0, tau), sigma, (n_flights, 1)) for _ in range(n_actuators)]


def test_offset_components_recover_within_and_between_scatter() -> None:
    rng = np.random.default_rng(10)
    sigma, tau = offset_components(_offset_population(rng, 60, 12))
    assert sigma[0] == pytest.approx(0.3, rel=0.15)
    assert tau[0] == pytest.approx(2.0, rel=0.25)
    # no offsets at all: tau estimated near 0, never negative
    sigma0, tau0 = offset_components([rng.normal(0, 1, (12, 1)) for _ in range(60)])
    assert sigma0[0] == pytest.approx(1.0, rel=0.15) and 0.0 <= tau0[0] < 0.35


def test_self_reference_sees_a_shift_smaller_than_the_production_scatter() -> None:
    """A shift of 3 flight-scatter units is invisible against the fleet (offsets sd 2.0 /
    0.3 = 6.7 units) and obvious against the actuator's own first flights."""
    rng = np.random.default_rng(11)
    names = ["WT.F_DMD"]
    train = _offset_population(rng, 40, 12)
    self_ref = FaultDetector(reference_flights=6).fit(train, names)
    fleet = FaultDetector(reference_flights=0).fit(train, names)
    assert self_ref.within_std_[0] == pytest.approx(0.3, rel=0.2)
    healthy = _offset_population(rng, 40, 30)
    for det in (self_ref, fleet):
        assert max(confidence_sequence(det, q, names).max() for q in healthy) < 0.98
    caught = {"self": 0, "fleet": 0}
    for q in _offset_population(rng, 40, 30):
        q[10:] += 3.0 * 0.3  # 3 flight-scatter units from flight 10 on
        caught["self"] += confidence_sequence(self_ref, q, names).max() >= 0.98
        caught["fleet"] += confidence_sequence(fleet, q, names).max() >= 0.98
    assert caught["self"] >= 36 and caught["fleet"] <= 8, caught


def test_a_fleet_referenced_feature_learns_no_offset_from_a_bimodal_start() -> None:
    """F_REWEAR is tested against the fleet: a pair whose first flights all fell in the low
    mode of a bimodal healthy feature does not judge its ordinary high flights against that
    unlucky reference, while a worn rod end still alarms. A self-referenced detector of the
    same data does judge them against it (twice the residual), and the unlucky starts among
    its healthy design sequences widen its healthy scale, so its bands are the blunter."""
    rng = np.random.default_rng(21)
    names = ["WL1.F_REWEAR"]

    def bimodal(n: int) -> np.ndarray:  # 60 % of flights near -0.6, 40 % near +0.9
        modes = np.where(rng.random(n) < 0.6, -0.6, 0.9)[:, np.newaxis]
        return modes + 0.15 * rng.standard_normal((n, 1))

    train = [bimodal(12) for _ in range(40)]
    fleet = FaultDetector().fit(train, names)
    own = FaultDetector(fleet_referenced=()).fit(train, names)
    sigma, tau = offset_components(train)
    assert fleet.between_std_[0] == 0.0
    assert fleet.within_std_[0] == pytest.approx(np.hypot(sigma[0], tau[0]))
    unlucky = np.r_[np.full((6, 1), -0.6), np.tile([[0.9], [0.9], [-0.6]], (10, 1))]
    high = unlucky[:, 0] > 0
    z_fleet = fleet.self_referenced(unlucky)[high, 0]
    z_own = own.self_referenced(unlucky)[high, 0]
    assert np.all(z_own > 1.5 * z_fleet) and np.all(z_fleet < 2.0), (z_fleet, z_own)
    assert np.all(fleet.band_[0, 1:] < own.band_[0, 1:] - 1.0), (fleet.band_, own.band_)
    assert confidence_sequence(fleet, unlucky, names).max() < 0.98
    worn = unlucky.copy()
    worn[12:] += 8.0  # a worn rod end moves the feature far beyond the healthy modes
    assert confidence_sequence(fleet, worn, names).max() >= 0.98
    st = DetectionState.new("WL1", names)
    for row in unlucky[:8]:
        judge_alone(fleet, st, {"WL1.F_REWEAR": float(row[0])})
    assert judge_alone(fleet, st, {"WL1.F_REWEAR": 0.9}).offset["WL1.F_REWEAR"] == 0.0
    again = FaultDetector.from_dict(json.loads(json.dumps(fleet.to_dict())))
    assert again.fleet_referenced == ("F_REWEAR",)


def test_a_few_odd_flights_do_not_make_an_eight_flight_alarm() -> None:
    """Three odd flights among eight move the running mean past the band; the running median
    (the default for the 8-flight window) does not move, and a sustained shift still alarms."""
    rng = np.random.default_rng(13)
    names = ["WT.F_A"]
    train = [rng.standard_normal((40, 1)) for _ in range(20)]
    robust = FaultDetector((1, 3, 8), reference_flights=0).fit(train, names)
    plain = FaultDetector((1, 3, 8), reference_flights=0, median_from=0).fit(train, names)
    odd = np.zeros((20, 1))
    odd[[8, 11, 14]] = 5.0  # three odd flights, three apart
    assert confidence_sequence(plain, odd, names).max() >= 0.98
    assert confidence_sequence(robust, odd, names).max() < 0.98
    drift = np.zeros((20, 1))
    drift[8:] = 3.0
    assert confidence_sequence(robust, drift, names).max() >= 0.98


def test_the_judge_matches_the_vectorised_sequence_and_reset_forgets_the_reference() -> None:
    rng = np.random.default_rng(12)
    names = ["WT.F_DMD", "WT.F_TTS"]
    det = FaultDetector().fit([np.c_[q, rng.normal(0, 1, (12, 1))]
                               for q in _offset_population(rng, 30, 12)], names)
    seq = np.c_[rng.normal(1.5, 0.3, 25), rng.normal(0, 1, 25)]
    seq[4, 1] = np.nan
    seq[18:, 0] += 1.0
    want = confidence_sequence(det, seq, names)
    st = DetectionState.new("WT", names)
    got = [judge_alone(det, st, dict(zip(names, row.tolist(), strict=True))) for row in seq]
    assert np.allclose([[r.confidence[n] for n in names] for r in got], want)
    assert len(st.reference["WT.F_DMD"]) == det.reference_flights == 6
    assert len(st.reference["WT.F_TTS"]) == 6  # the NaN flight does not enter it
    assert got[-1].offset["WT.F_DMD"] == pytest.approx(1.5, abs=0.3)
    # the first flight is judged against the fleet alone (no offset removed)
    assert got[0].offset["WT.F_DMD"] == 0.0
    st.reset()
    assert all(not r for r in st.reference.values())


def test_state_and_detector_round_trip_through_json() -> None:
    rng = np.random.default_rng(4)
    names = list(AIRCRAFT_FEATURES)
    det = FaultDetector().fit([rng.standard_normal((50, len(names)))], names)
    det2 = FaultDetector.from_dict(json.loads(json.dumps(det.to_dict())))
    st = new_state(det, "WL1")
    for _ in range(12):
        judge_alone(det, st, {n: float(rng.standard_normal()) for n in names})
    st2 = DetectionState.from_dict(json.loads(json.dumps(st.to_dict())))
    assert st2 == st
    z = {n: 9.0 for n in names}
    r1, r2 = judge_alone(det, st, z), judge_alone(det2, st2, z)
    assert r1 == r2 and st == st2
    st.reset()
    assert not st.alarm and st.n_flights == 0 and all(not h for h in st.history.values())
    with pytest.raises(ValueError):
        DetectionState.from_dict({"format": "other"})


def test_fleet_baseline_and_model_round_trip() -> None:
    rng = np.random.default_rng(5)
    flights = [_flight(rng) for _ in range(60)]
    fb = FleetBaseline().fit(flights)
    det = FaultDetector().fit([fb.zscore_matrix(flights)], AIRCRAFT_FEATURES)
    model = DetectionModel(fb, det)
    m2 = DetectionModel.from_dict(json.loads(json.dumps(model.to_dict())))
    f = _flight(rng, {"WT.F_DMD": 20.0})
    z1, z2 = fb.zscores(f), m2.baseline.zscores(f)
    assert z1 == pytest.approx(z2, nan_ok=True)  # negative F_SE / F_BDO have no log
    assert z1["WT.F_DMD"] > 10


def test_a_flight_far_outside_the_design_conditions_is_named_not_judged() -> None:
    """Design flights at 0-40 degC on the ground: a flight at 41 degC (within a quarter of the
    range beyond it) is judged; one at 60 degC on the wingtip is named with the range it left
    and the wingtip features that model the temperature; a constant condition of the design
    (the load) names nothing; a document without ranges (written before them) names nothing."""
    rng = np.random.default_rng(7)
    flights = [_flight(rng) for _ in range(80)]
    for f in flights:
        f.conditions["WT"]["temp_ground_c"] = float(rng.uniform(0.0, 40.0))
    fb = FleetBaseline().fit(flights)
    near, far = _flight(rng), _flight(rng)
    for f in (near, far):
        for p in ("WL1", "WL2", "WT"):
            f.conditions[p]["temp_ground_c"] = 20.0
            f.conditions[p]["load_rms_n"] = 5000.0
    near.conditions["WT"]["temp_ground_c"] = 41.0
    far.conditions["WT"]["temp_ground_c"] = 60.0
    assert fb.outside_design(near) == []
    [found] = fb.outside_design(far)
    assert (found.position, found.condition, found.value) == ("WT", "temp_ground_c", 60.0)
    assert 0.0 <= found.low < 5.0 and 35.0 < found.high <= 40.0
    assert found.features == [n for n in AIRCRAFT_FEATURES if n.startswith("WT.")]
    again = FleetBaseline.from_dict(json.loads(json.dumps(fb.to_dict())))
    assert [o.to_dict() for o in again.outside_design(far)] == [found.to_dict()]
    doc = fb.to_dict()
    for m in doc["models"].values():
        del m["cov_range"]
    assert FleetBaseline.from_dict(doc).outside_design(far) == []


def test_ratio_features_are_judged_on_their_log() -> None:
    """A healthy F_BDO is log-normal-like: a flight at 4x the median is an ordinary upper
    tail on the log scale (z about 2.3 at a log-sd of 0.6) but 5 robust scales out on the
    value's;
    a document written before log features reads values as they are."""
    rng = np.random.default_rng(6)
    flights = [_flight(rng) for _ in range(400)]
    for f in flights:
        f.summaries["WT.F_BDO"] = FeatureSummary(float(0.005 * np.exp(0.6 * rng.standard_normal())),
                                                 0.1, 100)
    odd = _flight(rng)
    odd.summaries["WT.F_BDO"] = FeatureSummary(0.02, 0.1, 100)
    on_log = FleetBaseline().fit(flights)
    assert 1.5 < on_log.zscores(odd)["WT.F_BDO"] < 3.5
    doc = on_log.to_dict()
    assert doc["log_features"] == ["F_SE", "F_BDO"]
    as_is = FleetBaseline(log_features=()).fit(flights)
    assert as_is.zscores(odd)["WT.F_BDO"] > 4.5
    del doc["log_features"]
    assert FleetBaseline.from_dict(doc).log_features == ()


def test_tuned_defaults_live_in_the_configs_and_serialise_as_before() -> None:
    """``FaultDetector()`` and ``FleetBaseline()`` are the configs' defaults, and a fitted
    detector's document carries exactly these hyper-parameters (values and key order):
    ``ema-detector/2`` sets its bands for a false-alarm rate (``ema-detector/1`` carried a
    ``band_margin`` on the largest healthy value instead; test_detection_bands.py loads one)."""
    assert UNITS == ("WL1", "WL2", "WT")
    assert DETECTION_DEFAULTS == DetectionConfig() == FaultDetector().config
    assert FaultDetector.from_config(DetectionConfig(reference_flights=0)).reference_flights == 0
    rng = np.random.default_rng(4)
    names = list(AIRCRAFT_FEATURES)
    doc = FaultDetector().fit([rng.standard_normal((30, len(names)))], names).to_dict()
    grows = {"F_TTS": 1, "F_DMD": 1, "F_SE": 1, "F_BDO": 1, "F_MTEL": 1, "F_MTWEAR": 1,
             "F_REWEAR": 1}
    three = {"F_TTS": 3, "F_DMD": 3, "F_MTEL": 3, "F_MTWEAR": 3, "F_REWEAR": 3}
    want = {"format": "ema-detector/2", "windows": [1, 3, 8], "alarm_confidence": 0.98,
            "band_floor": 3.0, "false_alarm_rate": 3e-5, "scale_quantile": 0.99,
            "directions": grows, "pool_positions": True, "surface_split_ratio": 1.5,
            "min_windows": three, "reference_flights": 6, "window_clip": 6.0, "median_from": 8,
            "fleet_referenced": ["F_REWEAR"]}
    assert {k: doc[k] for k in want} == want
    assert list(doc)[: len(want)] == list(want)
    assert list(doc["directions"]) == list(grows) and list(doc["min_windows"]) == list(three)
    assert BASELINE_DEFAULTS == BaselineConfig()
    fb = FleetBaseline()
    assert (fb.covariates, fb.ridge, fb.outlier_k, fb.min_evidence) == (
        ("temp_ground_c", "temp_mean_c", "load_rms_n", "speed_rms_rad_s"), 1.0, 6.0, 0.25)
    lb = LinearBaseline()
    assert (lb.covariates, lb.ridge, lb.outlier_k) == (BASELINE_DEFAULTS.covariates, 1.0, 6.0)


# --------------------------------------------------------------------------------------------
# on simulated campaigns: fit on DESIGN, score on VERIFICATION
# --------------------------------------------------------------------------------------------


@pytest.mark.slow
def test_no_false_alarm_on_healthy_verification_flights(verification_campaign,
                                                        verification_outcomes) -> None:
    healthy = [o for o in verification_outcomes if o.mode == "healthy"]
    n_flights = sum(o.n_flights for o in healthy)
    assert sum(o.false_alarms + o.other_unit_alarms for o in healthy) == 0
    # nor before the onset of any fault pattern
    assert sum(o.false_alarms for o in verification_outcomes) == 0
    # the requirement is stated on >= 250 healthy flights of >= 10 aircraft
    assert len({o.aircraft for o in healthy}) >= 10, "too few healthy aircraft in the campaign"
    assert n_flights >= 250, f"only {n_flights} healthy verification flights in the campaign"


@pytest.mark.slow
@pytest.mark.parametrize("mode", ["TTS", "DMD", "MTEL", "MTWEAR", "REWEAR"])
def test_progressive_faults_detected_before_half_life(dense_verification_outcomes, mode) -> None:
    """On the verification campaign with every 5th flight of a fault run rendered (the model
    is the quick design campaign's: the bands come from healthy flights, which both render).
    A winglet drive's motor features are read on the flights it drives, every 10th flight
    here, and grease ageing shows late: MTEL on a winglet drive gets until 65 % of its life
    (V-MTEL-03, WL1, a 170-flight life: 58.8 %; MTEL on the wingtip 25.5 %)."""
    prog = [o for o in dense_verification_outcomes if o.mode == mode]
    assert prog

    def bound(o: PatternOutcome) -> float:
        return 65.0 if o.mode == "MTEL" and o.position in ("WL1", "WL2") else 50.0

    late = [(o.id, o.mode, o.detection_pct_life) for o in prog
            if o.detected_index is None or not o.detection_pct_life < bound(o)]
    assert not late, late


@pytest.mark.slow
def test_no_false_alarm_before_onset_on_the_dense_campaign(dense_verification_outcomes) -> None:
    assert sum(o.false_alarms for o in dense_verification_outcomes) == 0


@pytest.mark.slow
def test_reached_levels_do_not_regress(verification_outcomes) -> None:
    """The quick campaign (every 21st flight of a fault run rendered) as it stands: every
    progressive fault detected, MTEL before 80 % of its life and REWEAR before 60 % (at most
    74.1 and 55.0 %: a winglet drive is read in each role on every 42nd flight there, one
    reading is 12-25 % of a life), the others before half life (at most 43.5 %)."""
    prog = [o for o in verification_outcomes if o.mode in ("TTS", "DMD", "MTEL", "MTWEAR",
                                                          "REWEAR")]
    assert len(prog) == 15 and all(o.detected_index is not None for o in prog)
    bound = {"MTEL": 80.0, "REWEAR": 60.0}
    assert all(o.detection_pct_life < bound.get(o.mode, 50.0) for o in prog), [
        (o.id, o.detection_pct_life) for o in prog]


@pytest.mark.slow
def test_step_faults_detected_within_three_flights(verification_outcomes) -> None:
    steps = [o for o in verification_outcomes if o.mode in ("SE", "BDO")]
    assert steps
    slow = [(o.id, o.mode, o.flights_after_onset) for o in steps
            if o.detected_index is None or o.flights_after_onset > 3]
    assert not slow, slow


@pytest.mark.slow
def test_summary_rows_cover_every_mode(verification_outcomes) -> None:
    rows = summarise(verification_outcomes)
    assert {r["mode"] for r in rows} >= {"healthy", "TTS", "DMD", "SE", "BDO", "MTEL",
                                          "MTWEAR", "REWEAR"}


def _winglet_pair_detector(rng: np.random.Generator) -> tuple[FaultDetector, list[str]]:
    names = ["WL1.F_MTEL", "WL1.F_DMD", "WL2.F_MTEL", "WL2.F_DMD"]
    return FaultDetector().fit([rng.standard_normal((200, 4)) for _ in range(8)], names), names


def _pair_run(det: FaultDetector, names: list[str], faulty: str, rng: np.random.Generator,
              *, share: float = 0.45, gate: bool = True) -> dict[str, int | None]:
    """A drift of the friction ratio on ``faulty``, ``share`` of it on its partner (the
    standby's back-driven drag, bench/partner_drag.py); each drive valid on alternate flights
    as in active-standby. The flight of each unit's first alarm (None: none)."""
    states = {u: DetectionState.new(u, [n for n in names if n.startswith(u)])
              for u in ("WL1", "WL2")}
    first: dict[str, int | None] = dict.fromkeys(states)
    for k in range(300):
        rise = 0.05 * max(k - 20, 0)
        active = "WL1" if k % 2 == 0 else "WL2"
        z = {n: float(rng.standard_normal()) for n in names}
        for u in states:
            if u != active:
                z[f"{u}.F_MTEL"] = float("nan")
        z[f"{active}.F_MTEL"] += rise if active == faulty else share * rise
        res = (update_units(det, states, z) if gate
               else {u: judge_alone(det, st, z) for u, st in states.items()})
        for u, r in res.items():
            if r.new_alarm:
                first[u] = k
    return first


@pytest.mark.parametrize("faulty", ["WL1", "WL2"])
def test_a_partner_s_friction_alarms_the_partner_not_the_healthy_drive(faulty) -> None:
    rng = np.random.default_rng(21)
    det, names = _winglet_pair_detector(rng)
    healthy = "WL2" if faulty == "WL1" else "WL1"
    gated = _pair_run(det, names, faulty, np.random.default_rng(5))
    assert gated[faulty] is not None and gated[healthy] is None
    # judged alone, the healthy drive alarms on its partner's drag: the pair is what holds it
    alone = _pair_run(det, names, faulty, np.random.default_rng(5), gate=False)
    assert alone[healthy] is not None
    assert alone[faulty] == gated[faulty]  # the faulty drive's own alarm is not delayed


def test_partner_held_leaves_each_drive_its_own_evidence() -> None:
    # levels: how far each unit's features have moved
    m = {"WL1": {"WL1.F_MTEL": 1.0, "WL1.F_DMD": 9.0},
         "WL2": {"WL2.F_MTEL": 4.0, "WL2.F_DMD": -1.0}, "WT": {"WT.F_MTEL": 50.0}}
    assert partner_held(m) == {"WL1": ["WL1.F_MTEL"]}  # only the coupled feature, only the pair
    assert partner_held({"WL1": m["WL1"], "WT": m["WT"]}) == {}  # no partner judged
    st = DetectionState.new("WL1", ["WL1.F_MTEL"])
    det = FaultDetector().fit([np.random.default_rng(0).standard_normal((200, 1))],
                              ["WL1.F_MTEL"])
    for _ in range(det.reference_flights):
        judge_alone(det, st, {"WL1.F_MTEL": 0.0})
    for _ in range(3):  # F_MTEL, a progressive fault's feature, alarms on 3 flights or more
        res = decide(det, st, observe(det, st, {"WL1.F_MTEL": 40.0}), held=["WL1.F_MTEL"])
    assert not res.alarm and res.held == ["WL1.F_MTEL"] and res.max_confidence > 0.98


def test_a_surface_whose_feature_scatters_more_gets_its_own_population() -> None:
    """The wingtip's screw-gap estimate scatters 2.5 times the winglet drives' (its own load
    spectrum presses the flanks differently): pooled with them, its flights are judged on a
    scatter they do not have; fitted per surface, each has its own, and the two winglet drives
    stay together. A feature whose surfaces agree stays pooled."""
    rng = np.random.default_rng(41)
    names = ["WL1.F_MTWEAR", "WL2.F_MTWEAR", "WT.F_MTWEAR", "WL1.F_DMD", "WL2.F_DMD",
             "WT.F_DMD"]
    scale = np.array([0.1, 0.1, 0.25, 0.2, 0.2, 0.22])
    seqs = [rng.standard_normal((150, 6)) * scale + rng.normal(0.0, 1.0, 6) for _ in range(10)]
    pooled = FaultDetector(surface_split_ratio=float("inf")).fit(seqs, names)
    apart = FaultDetector().fit(seqs, names)
    assert pooled.surface_split_ == [] and apart.surface_split_ == ["F_MTWEAR"]
    assert pooled.within_std_[0] == pooled.within_std_[2]
    assert apart.within_std_[0] == apart.within_std_[1]
    assert apart.within_std_[2] == pytest.approx(0.25, rel=0.1)
    assert apart.within_std_[0] == pytest.approx(0.1, rel=0.1)
    assert apart.within_std_[3] == apart.within_std_[5]  # F_DMD: the surfaces agree
    wt = [apart.self_referenced(q)[6:, 2] for q in seqs]
    assert np.std(np.concatenate(wt)) == pytest.approx(1.0, abs=0.1)
    wt_pooled = [pooled.self_referenced(q)[6:, 2] for q in seqs]
    assert np.std(np.concatenate(wt_pooled)) > 1.3
    back = FaultDetector.from_dict(apart.to_dict())
    assert back.surface_split_ == ["F_MTWEAR"] and back.surface_split_ratio == 1.5
