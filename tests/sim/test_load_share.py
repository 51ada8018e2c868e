"""The worn drive's load share: the stored table against the 12 kHz model, and its two uses."""

from __future__ import annotations

import numpy as np
import pytest

from sim_worker import build_aircraft
from sim_worker.calibration import measure_load_share
from sim_worker.faults import THRESHOLDS, FaultState
from sim_worker.fleet import WingletMode
from sim_worker.flight import estimate_summary
from sim_worker.load_share import life_integral, load_share, table

#: the load share belongs to an active-active pair
AA = WingletMode.ACTIVE_ACTIVE


@pytest.mark.slow
def test_stored_table_agrees_with_the_kernel():
    """Three fresh paired flights per point against the stored twelve: a kernel or scenario
    change that moves the load share shows here (then re-run ``sim-worker load-share``)."""
    grid = (0.0, 0.3, 1.0)
    fresh = measure_load_share(n_flights=3, grid=grid, workers=1, positions=("WL1", "WT"))
    for mode, curves in fresh["ratio"].items():
        for pos, curve in curves.items():
            stored = [load_share(mode, pos, s, winglet_mode=AA) for s in grid]
            assert np.allclose(curve, stored, rtol=0.25, atol=0.05), (mode, pos, curve, stored)


def test_a_worn_winglet_drive_hands_its_load_to_its_partner():
    doc = table()
    for mode in ("MTWEAR", "REWEAR"):
        for pos in ("WL1", "WL2"):
            curve = np.array(doc["ratio"][mode][pos])
            assert np.all(np.diff(curve) < 0), (mode, pos)  # falls with every step of wear
        # the wingtip drive is alone on its surface: no partner to take the load
        assert np.ptp(doc["ratio"][mode]["WT"]) < 0.05
    # rod-end free play at failure leaves the worn drive a small fraction of its work
    assert (load_share("REWEAR", "WL1", 1.0, winglet_mode=AA) < 0.2 < 0.8
            < load_share("REWEAR", "WL1", 0.0, winglet_mode=AA))
    # an active-standby pair needs none
    assert load_share("REWEAR", "WL1", 1.0, winglet_mode=WingletMode.ACTIVE_STANDBY) == 1.0


def test_estimate_scales_only_the_faulty_drives_work():
    ac = build_aircraft("I-SHARE1", "Turin", seed=3)
    thr = THRESHOLDS["REWEAR"]
    fault = FaultState("REWEAR", "WL2", 0.5 * thr, thr)

    def est(**kw):
        return estimate_summary(ac, 4, np.random.default_rng(8), duration_s=20.0,
                                winglet_mode=AA, **kw)

    blind, aware = est(), est(fault=fault)
    w = aware.actuators["WL2"].work_rod_end_n_m / blind.actuators["WL2"].work_rod_end_n_m
    assert w == pytest.approx(load_share("REWEAR", "WL2", 0.5, winglet_mode=AA)) < 0.5
    assert aware.actuators["WL2"].work_screw_n_m == blind.actuators["WL2"].work_screw_n_m
    assert aware.actuators["WL1"] == blind.actuators["WL1"]
    assert aware.actuators["WT"] == blind.actuators["WT"]


def test_life_integral_without_load_share_is_the_closed_form():
    c, onset = 0.05, 0.05
    assert life_integral("TTS", "WL1", onset, c, winglet_mode=AA) == pytest.approx(
        np.log((1 + c) / (onset + c)), rel=1e-4)
    # the winglet's falling share makes the same span need a faster wear rate
    assert (life_integral("REWEAR", "WL1", onset, 0.8, winglet_mode=AA)
            > 3 * life_integral("REWEAR", "WT", onset, 0.8, winglet_mode=AA))


@pytest.mark.parametrize(("mode", "position"), [("REWEAR", "WL1"), ("MTWEAR", "WL2"),
                                                ("MTWEAR", "WT")])
def test_an_operators_span_holds_on_average(mode, position):
    """What the test station does: the rate is set against the aircraft's average flight
    (:func:`reference_summary`), then flights advance the fault. Over eight runs the mean
    span is the operator's 60 flights within the process noise's scatter."""
    from sim_worker import advance_fault, new_fault, reference_summary
    from sim_worker.flight import flight_start

    ac = build_aircraft("I-SPAN01", "Vancouver", seed=21)
    ref = reference_summary(ac, position, duration_s=30.0, seed=4)
    spans = []
    for run in range(8):
        fault = new_fault(mode, position, np.random.default_rng([run, 1]), reference=ref,
                          span_flights=60)
        n = 0
        while not fault.failed and n < 400:
            index = 1000 * run + n
            summ = estimate_summary(ac, index, np.random.default_rng([run, n]), fault=fault,
                                    started_at=flight_start(index), duration_s=30.0)
            fault = advance_fault(fault, summ, np.random.default_rng([run, n, 2]))
            n += 1
        spans.append(n)
    assert 45 <= np.mean(spans) <= 80, spans
