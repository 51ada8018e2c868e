"""Metrics against hand-computed cases (server.phm.metrics)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from server.phm import metrics as m

# One scenario used throughout: predictions every 10 flights, failure at flight 50.
#   t       = 0   10  20  30  40
#   r* = 50-t = 50  40  30  20  10
#   r       = 80  30  33  21  10.5
T = np.array([0.0, 10.0, 20.0, 30.0, 40.0])
T_EOL = 50.0
R_TRUE = T_EOL - T
R_PRED = np.array([80.0, 30.0, 33.0, 21.0, 10.5])


def test_relative_accuracy_by_hand() -> None:
    # RA = 1 - |r* - r| / r*: 1-30/50, 1-10/40, 1-3/30, 1-1/20, 1-0.5/10
    expected = [0.4, 0.75, 0.9, 0.95, 0.95]
    np.testing.assert_allclose(m.relative_accuracy(R_PRED, R_TRUE), expected, rtol=0, atol=1e-12)
    # mean = 3.95 / 5
    assert m.mean_relative_accuracy(R_PRED, R_TRUE) == pytest.approx(0.79, abs=1e-12)


def test_cumulative_relative_accuracy_by_hand() -> None:
    # uniform weights: the mean RA
    assert m.cumulative_relative_accuracy(R_PRED, R_TRUE) == pytest.approx(0.79, abs=1e-12)
    # weights 1..5: (0.4*1 + 0.75*2 + 0.9*3 + 0.95*4 + 0.95*5) / 15 = 13.15 / 15
    w = [1, 2, 3, 4, 5]
    assert m.cumulative_relative_accuracy(R_PRED, R_TRUE, w) == pytest.approx(13.15 / 15, abs=1e-12)
    with pytest.raises(ValueError):
        m.cumulative_relative_accuracy(R_PRED, R_TRUE, [1, 1])


def test_relative_accuracy_rejects_nonpositive_truth() -> None:
    with pytest.raises(ValueError):
        m.relative_accuracy([1.0], [0.0])


def test_prognostic_horizon_relative_bounds() -> None:
    # +-20 % cones: [40,60] [32,48] [24,36] [16,24] [8,12]
    # inside?       no      no      yes     yes     yes   -> first of the final run is t=20
    assert m.prognostic_horizon(T, R_PRED, T_EOL, alpha=0.2) == pytest.approx(30.0)
    # nondimensional over the life from the first prediction (t=0): 30 / 50
    assert m.prognostic_horizon_nondimensional(T, R_PRED, T_EOL) == pytest.approx(0.6)
    # over the life from a fault onset at t=-10: 30 / 60
    assert m.prognostic_horizon_nondimensional(T, R_PRED, T_EOL, t_start=-10) == pytest.approx(0.5)


def test_prognostic_horizon_stay_versus_first_entry() -> None:
    pred = np.array([45.0, 30.0, 33.0, 30.0, 10.5])
    # inside? 45 in [40,60] yes; 30 in [32,48] no; 33 yes; 30 in [16,24] no; 10.5 yes
    # "falls and remains": only t=40 starts a run that lasts -> PH = 50 - 40
    assert m.prognostic_horizon(T, pred, T_EOL, stay=True) == pytest.approx(10.0)
    # Saxena's first entry: t=0 -> PH = 50
    assert m.prognostic_horizon(T, pred, T_EOL, stay=False) == pytest.approx(50.0)
    # never inside -> 0
    assert m.prognostic_horizon(T, np.full(5, 1000.0), T_EOL) == 0.0


def test_prognostic_horizon_eol_bounds() -> None:
    # constant band alpha * t_eol = 10: |r - r*| = 30, 10, 3, 1, 0.5 -> inside from t=10
    assert m.prognostic_horizon(T, R_PRED, T_EOL, bounds="eol") == pytest.approx(40.0)


def test_alpha_lambda_by_hand() -> None:
    # lambda 0.5: t_lambda = 0 + 0.5 * 50 = 25 -> last prediction at t=20: 33 in [24, 36]
    assert m.alpha_lambda(T, R_PRED, T_EOL, alpha=0.2, lam=0.5) is True
    # lambda 0.2: t_lambda = 10 -> prediction 30 vs [32, 48]
    assert m.alpha_lambda(T, R_PRED, T_EOL, alpha=0.2, lam=0.2) is False


def test_alpha_lambda_probability_by_hand() -> None:
    # r* = 30, alpha 0.2 -> [24, 36]; 25, 28, 31, 34 inside, 40 outside -> mass 0.8
    samples = [25.0, 28.0, 31.0, 34.0, 40.0]
    assert m.alpha_lambda_probability(samples, 30.0, beta=0.5) is True
    assert m.alpha_lambda_probability(samples, 30.0, beta=0.9) is False
    # weights put 0.6 on the outlier -> mass inside 0.4
    w = [0.1, 0.1, 0.1, 0.1, 0.6]
    assert m.alpha_lambda_probability(samples, 30.0, weights=w, beta=0.5) is False


def test_convergence_by_hand() -> None:
    # M = |relative error| = 0.6, 0.25, 0.1, 0.05, 0.05 (last interval dropped)
    err = np.abs(R_PRED - R_TRUE) / R_TRUE
    # area = 10 * (0.6 + 0.25 + 0.1 + 0.05) = 10
    # x_c = 0.5 * (100*0.6 + 300*0.25 + 500*0.1 + 700*0.05) / 10 = 0.5 * 220 / 10 = 11
    # y_c = 0.5 * 10 * (0.36 + 0.0625 + 0.01 + 0.0025) / 10 = 0.2175
    expected = math.sqrt(11.0**2 + 0.2175**2)
    assert m.convergence(T, err) == pytest.approx(expected, rel=1e-12)
    # a faster-converging error has a smaller C_M
    faster = np.array([0.6, 0.05, 0.05, 0.05, 0.05])
    assert m.convergence(T, faster) < m.convergence(T, err)


def test_detection_rates_by_hand() -> None:
    alarm = [True, False, False, True, True, False]
    faulty = [False, False, False, True, True, True]
    # healthy: 3 cases, 1 alarm -> 1/3; faulty: 3 cases, 1 without alarm -> 1/3
    assert m.false_alarm_rate(alarm, faulty) == pytest.approx(1 / 3)
    assert m.missed_detection_rate(alarm, faulty) == pytest.approx(1 / 3)
    assert math.isnan(m.false_alarm_rate([True], [True]))


def test_detection_time_by_hand() -> None:
    t = np.arange(10.0)
    alarm = np.zeros(10, dtype=bool)
    alarm[[2, 6, 7]] = True
    # the alarm at 2 precedes the onset 4.5 (a false alarm); first after onset at 6 -> 1.5
    assert m.detection_time(t, alarm, 4.5) == pytest.approx(1.5)
    assert math.isnan(m.detection_time(t, alarm, 8.0))


def test_event_rate_has_the_exact_interval() -> None:
    none = m.event_rate(0, 1000)
    assert none["rate"] == 0.0 and none["interval"][0] == 0.0
    assert none["interval"][1] == pytest.approx(1 - 0.05 ** (1 / 1000))  # one-sided 5 %
    three = m.event_rate(3, 1000)
    assert three["interval"][0] < 0.003 < three["interval"][1]
    assert m.event_rate(0, 0)["rate"] is None
