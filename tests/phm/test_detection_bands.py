"""Detection bands set for a stated false-alarm rate: synthetic healthy residuals of known
scale, where the threshold and the false-alarm rate have analytic values."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.special import ndtri

from server.phm.detection import (
    FaultDetector,
    confidence_sequence,
    healthy_statistics,
    new_state,
    running_statistics,
)
from server.phm.features import AIRCRAFT_FEATURES
from tests.phm.judging import judge_alone


def _healthy(rng: np.random.Generator, n_seq: int, n_flights: int, n_feat: int = 1,
             scale: float = 1.0) -> list[np.ndarray]:
    return [scale * rng.standard_normal((n_flights, n_feat)) for _ in range(n_seq)]


#: synthetic features grow with their fault (one-sided tests), as the real ones do
UP = {"F_A": 1, "F_B": 1, "F_C": 1}


def _threshold(det: FaultDetector) -> np.ndarray:
    """Where each test alarms: band + confidence margin (n_features, n_windows)."""
    return det.band_ + det.z_alarm


@pytest.mark.parametrize("scale", [1.0, 2.0])
def test_threshold_is_the_analytic_quantile_of_the_stated_rate(scale: float) -> None:
    """One feature, one one-flight window, the fleet test: the residual itself is judged, so
    the threshold is scale * z_{1 - rate}."""
    rng = np.random.default_rng(100)
    rate = 1e-3
    det = FaultDetector((1,), reference_flights=0, band_floor=0.0, false_alarm_rate=rate,
                        directions=UP)
    det.fit(_healthy(rng, 50, 200, scale=scale), ["WT.F_A"])
    assert det.tests_per_unit() == {"WT": 1}
    assert det.healthy_scale_[0, 0] == pytest.approx(scale, rel=0.05)
    assert _threshold(det)[0, 0] == pytest.approx(scale * ndtri(1 - rate), rel=0.05)


def test_rate_is_shared_among_the_tests_of_a_unit_and_per_side() -> None:
    """Sidak over the unit's (feature, window) tests allowed to alarm; a two-sided feature
    splits its share between the two tails."""
    rng = np.random.default_rng(101)
    rate = 1e-3
    names = ["WT.F_A", "WT.F_B", "WL1.F_A", "WL1.F_B"]
    det = FaultDetector((1, 3), reference_flights=0, band_floor=0.0, median_from=0,
                        false_alarm_rate=rate, directions={"F_A": 1, "F_B": 0},
                        min_windows={"F_B": 3}, pool_positions=False)
    det.fit(_healthy(rng, 40, 250, n_feat=4), names)
    assert det.tests_per_unit() == {"WT": 3, "WL1": 3}  # F_A: 1 and 3 flights; F_B: 3 only
    share = 1 - (1 - rate) ** (1 / 3)
    want = np.array([ndtri(1 - share), ndtri(1 - share / 2)] * 2)
    assert det.test_quantiles() == pytest.approx(want)
    # each column's threshold is its own scale (near 1) times its quantile
    assert np.allclose(det.healthy_scale_, 1.0, rtol=0.08)
    assert np.allclose(_threshold(det), det.healthy_scale_ * want[:, None])
    # the real detector: six actuator features (F_SE, F_BDO on 1, 3, 8 flights, the others on
    # 3 and 8) and a winglet drive's rod-end play on 3 and 8 flights
    full = FaultDetector().fit([rng.standard_normal((40, len(AIRCRAFT_FEATURES)))],
                               AIRCRAFT_FEATURES)
    assert full.tests_per_unit() == {"WL1": 16, "WL2": 16, "WT": 14}


def test_band_does_not_grow_with_the_number_of_healthy_flights() -> None:
    """Fitted on 200 and on 2000 healthy flights (default detector: self-reference, windows of
    1, 3 and 8 flights; no floor), the thresholds agree on average, within the noise of a
    0.99 quantile of 200 correlated values; the largest healthy S_w, the former band, grows by
    more than that."""
    rng = np.random.default_rng(102)
    names = ["WT.F_A"]

    def fit(n_seq: int) -> tuple[np.ndarray, np.ndarray]:
        seqs = _healthy(rng, n_seq, 20)
        det = FaultDetector(band_floor=0.0, min_windows={}, directions=UP).fit(seqs, names)
        stats = healthy_statistics(det, seqs, names)
        largest = np.array([stats[k][0].max() for k in range(len(det.windows))])
        return _threshold(det)[0], largest

    small = [fit(10) for _ in range(60)]  # 60 fits on 200 flights
    big = [fit(100) for _ in range(12)]  # 12 fits on 2000 flights
    thr_small = np.mean([t for t, _ in small], axis=0)
    thr_big = np.mean([t for t, _ in big], axis=0)
    # the analytic value where the statistic is a plain mean of unit-normal residuals: the
    # default rate shared among three one-sided tests (the self-reference adds a few percent)
    z = -ndtri(1 - (1 - 3e-5) ** (1 / 3))
    assert thr_big[:2] == pytest.approx(z, rel=0.06)
    assert thr_small == pytest.approx(thr_big, rel=0.1), (thr_small, thr_big)
    max_small = np.mean([m for _, m in small], axis=0)
    max_big = np.mean([m for _, m in big], axis=0)
    assert np.all(max_big - max_small > 0.5), (max_small, max_big)
    assert np.all(max_big - max_small > 1.5 * np.abs(thr_big - thr_small))


def test_realised_false_alarm_rate_is_the_stated_one_on_independent_tests() -> None:
    """Three independent one-flight tests of one unit: the share of fresh healthy flights on
    which any of them reaches the alarm confidence is the stated rate."""
    rng = np.random.default_rng(103)
    rate = 0.01
    names = ["WT.F_A", "WT.F_B", "WT.F_C"]
    det = FaultDetector((1,), reference_flights=0, band_floor=0.0, false_alarm_rate=rate,
                        directions=UP)
    det.fit(_healthy(rng, 100, 300, n_feat=3), names)
    fresh = _healthy(rng, 100, 500, n_feat=3)
    alarms = np.concatenate([confidence_sequence(det, q, names).max(axis=1) >= 0.98
                             for q in fresh])
    # 50,000 flights: 500 expected, sd 22, plus the scale's estimation error
    assert alarms.mean() == pytest.approx(rate, rel=0.2)


def test_realised_false_alarm_rate_stays_below_the_stated_one_with_overlapping_windows() -> None:
    """The default windows (1, 3, 8, the 8-flight one a median) and self-reference: the tests
    of a unit are correlated, so the Sidak share keeps the realised rate below the stated one,
    but not far below (the single flights and the windows still alarm on their own)."""
    rng = np.random.default_rng(104)
    rate = 0.02
    names = ["WT.F_A", "WT.F_B"]
    det = FaultDetector(band_floor=0.0, false_alarm_rate=rate, min_windows={}, directions=UP)
    det.fit(_healthy(rng, 200, 60, n_feat=2), names)
    fresh = _healthy(rng, 200, 100, n_feat=2)
    alarms = np.concatenate([confidence_sequence(det, q, names).max(axis=1) >= 0.98
                             for q in fresh])
    assert 0.4 * rate < alarms.mean() < 1.1 * rate, alarms.mean()


def test_heavier_tails_than_normal_widen_the_band() -> None:
    """Student-t residuals (3 degrees of freedom, unit MAD-scale near 1) get a larger scale
    than normal ones: the tail quantile sees what a MAD would not."""
    rng = np.random.default_rng(105)
    names = ["WT.F_A"]
    t3 = [rng.standard_t(3, (200, 1)) for _ in range(30)]
    det = FaultDetector((1,), reference_flights=0, band_floor=0.0, directions=UP).fit(t3, names)
    # the t3 99th percentile is 4.54, 1.95 normal sd
    assert det.healthy_scale_[0, 0] == pytest.approx(4.54 / ndtri(0.99), rel=0.1)


def test_the_scale_is_measured_on_what_the_judge_judges() -> None:
    """Healthy statistics are the oriented S_w of full windows only, held through flights
    without a value, as the online judge (`update_units`) judges them."""
    rng = np.random.default_rng(106)
    names = ["WT.F_A"]
    q = rng.standard_normal((12, 1))
    q[5] = np.nan
    det = FaultDetector((1, 3), reference_flights=0, median_from=0, directions=UP,
                        min_windows={"F_A": 3}).fit([q], names)
    stats = healthy_statistics(det, [q], names)
    s3 = running_statistics(q, 3)[:, 0]
    # 3 valid values from flight 2 on; flight 5 (no value) holds flight 4's statistic
    assert stats[1][0] == pytest.approx(s3[2:])
    assert s3[5] == s3[4]
    # the one-flight window may not alarm (min 3): its statistics count from the first flight
    held = q[:, 0].copy()
    held[5] = held[4]
    assert stats[0][0] == pytest.approx(held)


def test_an_ema_detector_1_document_still_loads_with_its_bands() -> None:
    rng = np.random.default_rng(107)
    names = list(AIRCRAFT_FEATURES)
    det = FaultDetector().fit([rng.standard_normal((50, len(names)))], names)
    doc = json.loads(json.dumps(det.to_dict()))
    assert doc["format"] == "ema-detector/2"
    old = {k: v for k, v in doc.items()
           if k not in ("false_alarm_rate", "scale_quantile", "healthy_scale")}
    old.update({"format": "ema-detector/1", "band_margin": 0.0,
                "band": (np.asarray(doc["band"]) + 0.7).tolist()})  # a max rule's bands
    legacy = FaultDetector.from_dict(old)
    assert np.allclose(legacy.band_, np.asarray(doc["band"]) + 0.7)
    assert legacy.false_alarm_rate is None and legacy.config.false_alarm_rate is None
    assert np.isnan(legacy.healthy_scale_).all()
    z = {n: 5.0 for n in names}
    st = new_state(legacy, "WT")
    assert (judge_alone(legacy, st, z).max_confidence
            < judge_alone(det, new_state(det, "WT"), z).max_confidence)
    # round trip of the new document
    again = FaultDetector.from_dict(doc)
    assert np.allclose(again.band_, det.band_) and again.config == det.config
    assert np.allclose(again.healthy_scale_, det.healthy_scale_, equal_nan=True)
    with pytest.raises(ValueError):
        FaultDetector.from_dict({**doc, "format": "ema-detector/9"})
    with pytest.raises(ValueError):
        FaultDetector(false_alarm_rate=0.0)
