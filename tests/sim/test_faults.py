"""Each fault moves the signals the way its physics says (signals at sensor level, 800 Hz)."""

from __future__ import annotations

import numpy as np
import pytest

from sim_worker.faults import THRESHOLDS, FaultState
from sim_worker.kernel import D
from sim_worker.params import P
from tests.sim.helpers import const, make_scenario, ramp, run

WT = 2
IA, IB, IC, VA, VB, VC, TH, X = range(8)


def _fault(mode: str, severity: float, position: str = "WT") -> FaultState:
    return FaultState(mode=mode, position=position, severity=severity,
                      threshold=THRESHOLDS[mode], phase_rad=0.7)


def _triangle(t: np.ndarray, amp: float = 0.008, period: float = 2.0) -> np.ndarray:
    """Slow triangle (8 mm/s peak-to-peak over a period): reversals, electrical freq < 80 Hz."""
    phase = (t / period) % 1.0
    return amp * (4.0 * np.abs(phase - 0.5) - 1.0)


def _moving_wt(duration: float = 4.0, load: float = -800.0):
    return make_scenario(duration, const(0.0), _triangle, const(0.0),
                         lambda t: load - 4.0e4 * _triangle(t))


def _amp(sig: np.ndarray) -> np.ndarray:
    return np.sqrt((2.0 / 3.0) * (sig[:, IA] ** 2 + sig[:, IB] ** 2 + sig[:, IC] ** 2))


def test_tts_common_node_current_grows_with_severity(aircraft):
    sc = _moving_wt()
    var, asym = [], []
    for sev in (0.0, 0.02, 0.05, 0.09):
        res = run(aircraft, sc, _fault("TTS", sev))
        sig = res.signals[:, WT]
        var.append(np.var(sig[:, IA] + sig[:, IB] + sig[:, IC]))
        rms = np.sqrt(np.mean(sig[:, IA:IC + 1] ** 2, axis=0))
        asym.append((rms.max() - rms.min()) / rms.mean())
    assert np.all(np.diff(var) > 0), var
    assert var[-1] > 3.0 * var[0]
    assert asym[-1] > asym[0] + 0.01, asym  # phase currents become asymmetric


def test_dmd_needs_more_current_for_the_same_load(aircraft):
    h = 0.15
    sc = make_scenario(3.0, const(0.0), lambda t: ramp(t, 0.5, 2.5, 0.0, 0.008), const(0.0),
                       const(-1500.0))
    win = (sc.t > 1.8) & (sc.t < 2.4)
    healthy = _amp(run(aircraft, sc).signals[:, WT])[win].mean()
    faulty = _amp(run(aircraft, sc, _fault("DMD", h)).signals[:, WT])[win].mean()
    np.testing.assert_allclose(faulty / healthy, 1.0 / (1.0 - h), rtol=0.03)


def test_mtel_raises_the_current_to_move_and_hold_against_the_load(aircraft):
    sc = make_scenario(3.0, const(0.0), lambda t: ramp(t, 0.5, 2.5, 0.0, 0.008), const(0.0),
                       const(-1500.0))
    win = (sc.t > 1.8) & (sc.t < 2.4)
    res_h = run(aircraft, sc)
    res_f = run(aircraft, sc, _fault("MTEL", 0.10))
    i_h = _amp(res_h.signals[:, WT])[win].mean()
    i_f = _amp(res_f.signals[:, WT])[win].mean()
    eta_h, eta_f = res_h.params[WT, P.ETA_D], res_f.params[WT, P.ETA_D]
    np.testing.assert_allclose(eta_h - eta_f, 0.10, atol=1e-6)
    # efficiency ratio plus the grown drag torque
    r = res_h.params[WT, P.R_SCREW]
    kt_i = i_h / (1500.0 * r / eta_h + res_h.params[WT, P.TC])
    expected = kt_i * (1500.0 * r / eta_f + res_f.params[WT, P.TC])
    np.testing.assert_allclose(i_f, expected, rtol=0.03)
    assert i_f > 1.1 * i_h


def test_bdo_unbalances_the_phase_voltages(aircraft):
    sc = _moving_wt()
    win = sc.t > 0.5
    sig_h = run(aircraft, sc).signals[win, WT]
    sig_f = run(aircraft, sc, _fault("BDO", 1.0)).signals[win, WT]

    std_h = sig_h[:, VA:VC + 1].std(axis=0)
    std_f = sig_f[:, VA:VC + 1].std(axis=0)
    # the controller fights the missing switch: phase voltages swing far more ...
    assert std_f.min() > 3.0 * std_h.max()
    # ... and most on the faulty leg (imbalance between phases)
    assert std_f[0] > 1.5 * max(std_f[1], std_f[2])
    assert std_h.max() < 1.1 * std_h.min()


def test_se_adds_current_ripple_at_shaft_frequency(aircraft):
    # constant speed 10 mm/s = 2 rev/s of the shaft, under load
    sc = make_scenario(3.0, const(0.0), lambda t: ramp(t, 0.2, 2.9, -0.012, 0.015), const(0.0),
                       const(-1000.0))
    win = (sc.t > 0.8) & (sc.t < 2.8)

    def ripple(res) -> float:
        sig = res.signals[win, WT]
        theta = sig[:, TH]
        amp = _amp(sig)
        amp = amp - amp.mean()
        return float(np.hypot(np.mean(amp * np.cos(theta)), np.mean(amp * np.sin(theta))) * 2)

    r_h = ripple(run(aircraft, sc))
    r_f = ripple(run(aircraft, sc, _fault("SE", 0.3)))
    assert r_f > 5.0 * r_h, (r_h, r_f)
    assert r_f > 0.05  # A


@pytest.mark.parametrize("extra", [0.0, 0.2e-3])
def test_screw_backlash_is_the_lost_motion_between_lvdt_and_shaft(aircraft, extra):
    """Unloaded reversals: LVDT minus r * theta differs between the two directions of motion by
    the total screw backlash (new play + wear)."""
    sc = make_scenario(4.0, const(0.0), lambda t: _triangle(t, 0.005), const(0.0), const(0.0))
    res = run(aircraft, sc, _fault("MTWEAR", extra) if extra else None)
    sig = res.signals[:, WT]
    r = res.params[WT, P.R_SCREW]
    lost = sig[:, X] - r * sig[:, TH]
    v = np.gradient(sc.x_cmd[:, WT])
    # steady parts of the up and down strokes (away from the reversals)
    phase = (sc.t / 2.0) % 1.0
    up = (v > 0) & (np.abs(phase - 0.75) < 0.15) & (sc.t > 0.5)
    down = (v < 0) & (np.abs(phase - 0.25) < 0.15) & (sc.t > 0.5)
    measured = lost[down].mean() - lost[up].mean()
    expected = res.params[WT, P.BL_SCREW]
    np.testing.assert_allclose(measured, expected, atol=3e-6 + 0.05 * expected)


def test_rod_end_backlash_shows_between_the_two_winglet_lvdts(aircraft):
    """A worn rod end on WL1: when the hinge load reverses, WL1's rod crosses its play while
    WL2 holds the tab, so LVDT1 - LVDT2 jumps by about the rod-end backlash."""
    play = 1.0e-3
    sc = make_scenario(4.0, const(0.005), const(0.0),
                       lambda t: np.where(t < 2.0, -1000.0, 1000.0), const(0.0))
    res = run(aircraft, sc, _fault("REWEAR", play, "WL1"))
    d = res.signals[:, 0, X] - res.signals[:, 1, X]
    before = d[(sc.t > 1.2) & (sc.t < 1.9)].mean()
    after = d[(sc.t > 3.2) & (sc.t < 3.9)].mean()
    total = res.params[0, P.BL_ROD]
    np.testing.assert_allclose(abs(after - before), total, rtol=0.15)
    res_h = run(aircraft, sc)
    d_h = res_h.signals[:, 0, X] - res_h.signals[:, 1, X]
    jump_h = abs(d_h[(sc.t > 3.2) & (sc.t < 3.9)].mean() - d_h[(sc.t > 1.2) & (sc.t < 1.9)].mean())
    assert jump_h < 0.1 * total


def test_faults_enter_only_their_actuator(aircraft):
    sc = _moving_wt(2.0)
    res_h = run(aircraft, sc, seed=3)
    res_f = run(aircraft, sc, _fault("DMD", 0.1, "WL1"), seed=3)
    np.testing.assert_array_equal(res_h.truth[:, WT, D.IQ], res_f.truth[:, WT, D.IQ])
    assert not np.array_equal(res_h.truth[:, 0, D.IQ], res_f.truth[:, 0, D.IQ])
