"""Healthy bands of the signal-quality figures, the sensor findings they give, and how the
chain judges the features of a flight with a finding."""

from __future__ import annotations

import math

import numpy as np
import pytest

from server.phm.baselines import FleetBaseline
from server.phm.detection import FaultDetector, new_state
from server.phm.features import AIRCRAFT_FEATURES, FEATURE_SENSORS, FeatureSummary, FlightFeatures
from server.phm.sensor_health import (
    NoiseSensitivity,
    SensorBands,
    SensorModel,
    channel_sensor,
)
from server.vocabulary import POSITIONS, SIGNALS
from tests.phm.judging import judge_alone

FLOOR = {"ia": 0.057, "ib": 0.057, "ic": 0.057, "va": 1.4, "vb": 1.4, "vc": 1.4,
         "theta": 2.0e-4, "x": 2.1e-6, "i_sum": 0.041, "v_sum": 0.8}
LSB = {"ia": 2.0**-5, "ib": 2.0**-5, "ic": 2.0**-5, "va": 2.0**-3, "vb": 2.0**-3,
       "vc": 2.0**-3, "theta": 9.6e-5, "x": 2.0**-19}


def _quality(rng: np.random.Generator, *, scale: dict[str, float] | None = None,
             offset_m: float = -10e-6) -> dict[str, dict[str, float]]:
    """One healthy flight's figures: floors scattered 4 % from flight to flight."""
    scale = scale or {}
    out = {}
    for p in POSITIONS:
        for s in SIGNALS:
            ch = f"{p}.{s}"
            out[ch] = {"noise": FLOOR[s] * scale.get(ch, 1.0) * math.exp(rng.normal(0, 0.04)),
                       "lsb": LSB[s], "stuck": 0.0, "saturated": 0.0}
        for s in ("i_sum", "v_sum"):
            ch = f"{p}.{s}"
            out[ch] = {"noise": FLOOR[s] * scale.get(ch, 1.0) * math.exp(rng.normal(0, 0.04))}
        out[f"{p}.x"]["offset"] = offset_m + rng.normal(0.0, 6e-6)
    return out


@pytest.fixture(scope="module")
def bands() -> SensorBands:
    rng = np.random.default_rng(0)
    return SensorBands().fit([_quality(rng) for _ in range(300)])


def test_healthy_flights_give_no_finding(bands: SensorBands) -> None:
    rng = np.random.default_rng(1)
    assert sum(len(bands.assess(_quality(rng))) for _ in range(300)) == 0


def test_a_noisier_channel_is_named_with_its_floor_and_band(bands: SensorBands) -> None:
    rng = np.random.default_rng(2)
    found = bands.assess(_quality(rng, scale={"WT.x": 1.5}))
    assert [(f.channel, f.sensor, f.metric) for f in found] == [("WT.x", "lvdt", "noise")]
    f = found[0]
    assert f.value > f.high and f.low == 0.0
    assert f.to_dict()["sensor"] == "lvdt"


def test_a_quieter_channel_is_no_finding(bands: SensorBands) -> None:
    assert bands.assess(_quality(np.random.default_rng(3), scale={"WT.i_sum": 0.5})) == []


def test_a_phase_floor_alone_is_no_finding(bands: SensorBands) -> None:
    """A phase channel's floor carries the drive's own ripple (an inverter fault): the sensor
    is judged on the currents' sum."""
    assert bands.assess(_quality(np.random.default_rng(3), scale={"WT.ia": 50.0})) == []


def test_offset_step_stuck_and_rail_findings(bands: SensorBands) -> None:
    q = _quality(np.random.default_rng(4))
    q["WL1.x"]["offset"] = 120e-6
    q["WT.va"]["stuck"] = 0.2
    q["WT.theta"]["saturated"] = 0.05
    q["WL2.ib"]["lsb"] = 4 * LSB["ib"]
    found = {(f.channel, f.metric) for f in bands.assess(q)}
    assert found == {("WL1.x", "offset"), ("WT.va", "stuck"), ("WT.theta", "saturated"),
                     ("WL2.ib", "lsb")}


def test_bands_round_trip_through_json(bands: SensorBands) -> None:
    again = SensorBands.from_dict(bands.to_dict())
    assert again.bands_ == bands.bands_ and again.floor_medians_ == bands.floor_medians_
    q = _quality(np.random.default_rng(5), scale={"WL2.v_sum": 2.0})
    assert [f.to_dict() for f in again.assess(q)] == [f.to_dict() for f in bands.assess(q)]


def _sensitivity() -> NoiseSensitivity:
    s = NoiseSensitivity()
    s.bias_ = {g: dict.fromkeys(sensors, 0.0) for g, sensors in FEATURE_SENSORS.items()}
    s.variance_ = {g: dict.fromkeys(sensors, 0.0) for g, sensors in FEATURE_SENSORS.items()}
    s.bias_["F_TTS"]["current"] = 0.5
    s.variance_["F_TTS"]["current"] = 1.0
    s.variance_["F_REWEAR"]["lvdt"] = 0.2
    return s


Z = {n: 0.1 for n in AIRCRAFT_FEATURES}


def test_no_finding_changes_nothing(bands: SensorBands) -> None:
    judged = SensorModel(bands, _sensitivity()).judge(_quality(np.random.default_rng(6)), Z)
    assert judged.findings == [] and judged.z == Z and judged.extra_variance == {}


def test_a_noisier_current_sensor_widens_and_shifts_its_own_features(
        bands: SensorBands) -> None:
    q = _quality(np.random.default_rng(7), scale={"WT.i_sum": 2.0})
    judged = SensorModel(bands, _sensitivity()).judge(q, Z)
    e = judged.extra_variance["WT.F_TTS"]  # r^2 - 1 with r about 2: about 3
    assert 2.4 < e < 3.6
    assert judged.z["WT.F_TTS"] == pytest.approx(0.1 - 0.5 * e)
    # nothing of the other actuators moves; no feature is set aside
    assert all(judged.z[n] == Z[n] for n in Z if not n.startswith("WT."))
    assert set(judged.extra_variance) <= {n for n in Z if n.startswith("WT.")}
    assert judged.set_aside == []
    assert [f.channel for f in judged.for_position("WT")] == ["WT.i_sum"]


def test_one_noisier_winglet_lvdt_widens_both_drives_rod_end_play_by_half(
        bands: SensorBands) -> None:
    """The rod-end play reads both winglet LVDTs: one noisier LVDT adds half its excess."""
    q = _quality(np.random.default_rng(8), scale={"WL1.x": 2.0})
    judged = SensorModel(bands, _sensitivity()).judge(q, Z)
    r2 = (q["WL1.x"]["noise"] / bands.floor_medians_["WL1.x"]) ** 2
    for p in ("WL1", "WL2"):
        assert judged.extra_variance[f"{p}.F_REWEAR"] == pytest.approx(0.2 * (r2 - 1.0) / 2.0)


def test_a_stuck_channel_sets_aside_the_features_that_read_it(bands: SensorBands) -> None:
    q = _quality(np.random.default_rng(9))
    q["WT.x"]["stuck"] = 0.5
    judged = SensorModel(bands, _sensitivity()).judge(q, Z)
    readers = {f"WT.{g}" for g, sensors in FEATURE_SENSORS.items()
               if "lvdt" in sensors and g != "F_REWEAR"}
    assert set(judged.set_aside) == readers
    assert all(math.isnan(judged.z[n]) for n in readers)


def test_without_a_learned_sensitivity_a_noisier_sensor_sets_its_features_aside(
        bands: SensorBands) -> None:
    q = _quality(np.random.default_rng(10), scale={"WT.theta": 3.0})
    judged = SensorModel(bands, None).judge(q, Z)
    assert set(judged.set_aside) == {f"WT.{g}" for g in FEATURE_SENSORS if g != "F_REWEAR"}


def test_channel_sensor() -> None:
    assert channel_sensor("WL2.vb") == ("WL2", "voltage")
    assert channel_sensor("WT.i_sum") == ("WT", "current")


def test_extra_variance_widens_the_detector_flight_scatter() -> None:
    det = FaultDetector(windows=(1,))
    det.feature_names_ = ["WT.F_TTS"]
    det.within_std_ = np.array([1.0])
    det.between_std_ = np.array([0.0])
    det.band_ = np.array([[3.0]])
    plain, widened = new_state(det, "WT"), new_state(det, "WT")
    judge_alone(det, plain, {"WT.F_TTS": 6.0})
    judge_alone(det, widened, {"WT.F_TTS": 6.0}, {"WT.F_TTS": 3.0})
    assert plain.history["WT.F_TTS"][-1] == pytest.approx(6.0)
    assert widened.history["WT.F_TTS"][-1] == pytest.approx(3.0)  # 6 / sqrt(1 + 3)


def test_the_effect_scales_with_the_flights_evidence(bands: SensorBands) -> None:
    q = _quality(np.random.default_rng(11), scale={"WT.i_sum": 2.0})
    model = SensorModel(bands, _sensitivity())
    full = model.judge(q, Z, {"WT.F_TTS": 1.0})
    thin = model.judge(q, Z, {"WT.F_TTS": 4.0})  # a quarter of the usual valid windows
    assert thin.extra_variance["WT.F_TTS"] == pytest.approx(4 * full.extra_variance["WT.F_TTS"])
    assert 0.1 - thin.z["WT.F_TTS"] == pytest.approx(4 * (0.1 - full.z["WT.F_TTS"]))


class _Baseline:
    """Residuals are the stored values (``F_SE``'s its log over ``LOG_SCALE``); the healthy
    median is 100 valid windows."""

    min_evidence = 0.25
    log_features = ("F_SE",)

    def __init__(self, names: list[str]) -> None:
        self.min_valid_ = dict.fromkeys(names, 25.0)
        self.feature_names_ = tuple(names)

    def to_physical(self, z: dict[str, float]) -> dict[str, float]:
        return {n: v * LOG_SCALE if n.endswith("F_SE") else v for n, v in z.items()}

    def zscores(self, flight: FlightFeatures) -> dict[str, float]:
        return {n: s.value for n, s in flight.summaries.items()}

    # the baseline's own evidence weights, on these valid-window counts
    evidence_weights = FleetBaseline.evidence_weights
    _typical_valid = FleetBaseline._typical_valid


LOG_SCALE = 0.5


def _study_pair(rng: np.random.Generator, sensor: str, z_twin: float, z_study: float,
                n_valid: int = 100, ratio: float = 2.0) -> tuple[FlightFeatures, FlightFeatures]:
    """(study, twin) flights of one feature whose ``sensor`` floor is ``ratio`` times the
    twin's in the study flight."""
    channel = {"current": "WT.i_sum", "voltage": "WT.v_sum"}[sensor]
    q_twin = _quality(rng)
    q_study = {ch: dict(v) for ch, v in q_twin.items()}
    q_study[channel]["noise"] *= ratio
    return (FlightFeatures({"X": FeatureSummary(z_study, 0.0, n_valid)}, {}, quality=q_study),
            FlightFeatures({"X": FeatureSummary(z_twin, 0.0, n_valid)}, {}, quality=q_twin))


def _named(flight: FlightFeatures, name: str) -> FlightFeatures:
    return FlightFeatures({name: flight.summaries["X"]}, {}, quality=flight.quality)


def test_added_scatter_is_what_the_study_flights_gain_not_a_scaled_copy() -> None:
    """Study flights that add independent noise of variance 0.1 e w to their twins' residuals
    (not a scaled copy of the twin's noise): the added scatter per unit e w is 0.1; the
    scaled-noise estimator gave (r + 1) / (r - 1) = 3 times it."""
    rng = np.random.default_rng(21)
    pairs = []
    for k in range(240):
        n_valid = int(rng.choice([50, 100, 200]))
        w = 100 / n_valid
        twin_z = rng.normal(0.0, 1.0) + rng.normal(0.0, 0.5) * math.sqrt(w)
        study, twin = _study_pair(rng, "current", twin_z,
                                  twin_z + rng.normal(0.0, math.sqrt(0.1 * 3.0 * w)), n_valid)
        pairs.append(("current", f"P{k % 6}", _named(study, "WT.F_TTS"),
                      _named(twin, "WT.F_TTS")))
    s = NoiseSensitivity().fit(pairs, _Baseline(["WT.F_TTS"]))
    assert s.variance_["F_TTS"]["current"] == pytest.approx(0.1, abs=0.03)
    assert s.bias_["F_TTS"]["current"] == 0.0


def _power_study(rng: np.random.Generator, shares: dict[str, float],
                 n: int = 100) -> NoiseSensitivity:
    """A study of F_SE whose noise adds power: doubling a sensor (e = 3) adds ``3 share`` of
    the healthy power (1) to each twin flight's own power, whatever that is."""
    pairs = []
    for sensor, share in shares.items():
        for k in range(n):
            log_twin = rng.normal(0.0, LOG_SCALE)
            power = math.exp(2.0 * log_twin) + 3.0 * share
            log_study = 0.5 * math.log(power) + rng.normal(0.0, 0.01)
            study, twin = _study_pair(rng, sensor, log_twin / LOG_SCALE,
                                      log_study / LOG_SCALE)
            pairs.append((sensor, f"{sensor}{k % 4}", _named(study, "WT.F_SE"),
                          _named(twin, "WT.F_SE")))
    return NoiseSensitivity().fit(pairs, _Baseline(["WT.F_SE"]))


def test_a_magnitude_on_its_log_adds_its_sensors_in_power() -> None:
    """F_SE's noise power is the current sensor's (share 0.6) and the voltage sensor's
    (0.4): a healthy flight with both doubled moves its log by log(1 + 3) / 2, less than
    the two sensors' shifts summed."""
    shares = {"current": 0.6, "voltage": 0.4}
    s = _power_study(np.random.default_rng(22), shares)
    assert s.noise_power_["F_SE"] == pytest.approx(shares, abs=0.05)
    both, _ = s.effect("WT.F_SE", {"current": 3.0, "voltage": 3.0})
    alone = sum(s.effect("WT.F_SE", {sensor: 3.0})[0] for sensor in shares)
    assert both * LOG_SCALE == pytest.approx(0.5 * math.log(4.0), abs=0.03)
    assert alone > 1.3 * both
    again = NoiseSensitivity.from_dict(s.to_dict())
    assert again.effect("WT.F_SE", {"current": 3.0}) == s.effect("WT.F_SE", {"current": 3.0})


def test_a_fault_keeps_its_own_power_when_the_noise_is_taken_off() -> None:
    """A static eccentricity's flight carries 20 times the healthy power: with both sensors
    doubled (3 healthy powers added) its judged value is its own power's, log(21) / 2; a
    constant shift of the healthy flights' log(4) / 2 would have taken 0.63 off its log.
    A flight quieter than the noise alone is shifted no further than a healthy one."""
    s = _power_study(np.random.default_rng(23), {"current": 0.6, "voltage": 0.4})
    e = {"current": 3.0, "voltage": 3.0}
    z = 0.5 * math.log(21.0 + 3.0) / LOG_SCALE
    bias, _ = s.effect("WT.F_SE", e, z=z)
    assert (z - bias) * LOG_SCALE == pytest.approx(0.5 * math.log(21.0), abs=0.02)
    healthy, _ = s.effect("WT.F_SE", e)
    quiet, _ = s.effect("WT.F_SE", e, z=-3.0)
    assert quiet == healthy


def test_a_document_of_twin_relative_power_shares_is_judged_as_it_was_fitted() -> None:
    """A document written before the additive noise power (``power``: shares of the twin's
    power) shifts every flight by log(1 + sum share e) / 2, whatever the flight's power."""
    doc = {"bias": {}, "variance": {}, "log_scale": {"WT.F_SE": LOG_SCALE},
           "power": {"F_SE": {"current": 1.0}}}
    old = NoiseSensitivity.from_dict(doc)
    want = 0.5 * math.log(4.0) / LOG_SCALE
    assert old.effect("WT.F_SE", {"current": 3.0}, z=5.0)[0] == pytest.approx(want)
    assert NoiseSensitivity.from_dict(old.to_dict()).to_dict() == old.to_dict()


def test_noise_sensitivity_recovers_a_known_bias_and_scatter() -> None:
    """Twin and study flights whose F_TTS residuals differ by (r - 1) n + bias e w, n the
    twin's noise error (sd 0.5), r = 2 on the WT current sensor: per unit e w the fit gives
    the bias and var(n)."""
    rng = np.random.default_rng(12)
    names = ["WT.F_TTS"]
    pairs = []
    for k in range(120):
        n_valid = int(rng.choice([50, 100, 200]))
        w = 100 / n_valid
        noise = rng.normal(0.0, 0.5) * math.sqrt(w)
        base = rng.normal(0.0, 1.0)
        q_twin = _quality(rng)
        q_study = {ch: dict(v) for ch, v in q_twin.items()}
        q_study["WT.i_sum"]["noise"] *= 2.0
        twin = FlightFeatures({"WT.F_TTS": FeatureSummary(base + noise, 0.0, n_valid)}, {},
                              quality=q_twin)
        study = FlightFeatures({"WT.F_TTS": FeatureSummary(base + 2 * noise + 0.4 * 3 * w, 0.0,
                                                           n_valid)}, {}, quality=q_study)
        pairs.append(("current", f"P{k % 4}", study, twin))
    s = NoiseSensitivity().fit(pairs, _Baseline(names))
    assert s.bias_["F_TTS"]["current"] == pytest.approx(0.4, abs=0.02)
    assert s.variance_["F_TTS"]["current"] == pytest.approx(0.25, rel=0.3)
    again = NoiseSensitivity.from_dict(s.to_dict())
    assert (again.effect("WT.F_TTS", {"current": 3.0}, 2.0)
            == s.effect("WT.F_TTS", {"current": 3.0}, 2.0))


def test_evidence_weights_against_the_healthy_median() -> None:
    flight = FlightFeatures({"WT.F_SE": FeatureSummary(0.0, 0.0, 50),
                             "WT.F_TTS": FeatureSummary(0.0, 0.0, 0)}, {})
    w = _Baseline(["WT.F_SE", "WT.F_TTS"]).evidence_weights(flight)
    assert w == {"WT.F_SE": 2.0, "WT.F_TTS": 100.0}
