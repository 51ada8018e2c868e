"""Each per-feature function of server.phm.features called on its own, on 80 Hz inputs whose
answer the physics gives (exact least-squares fits, balanced three-phase sets, a hold)."""

from __future__ import annotations

import numpy as np
import pytest

from server.phm.features import (
    FeatureConfig,
    MotorConstants,
    actuator_steps,
    estimated_flux,
    filter_alpha,
    flux_deficit,
    flux_modulation,
    friction_ratio,
    leakage_conductance,
    screw_gap,
    validity_windows,
    voltage_imbalance,
    winding_resistance,
    winding_temperature,
)

N = 4000  # 80 Hz steps (50 s)
MC = MotorConstants()
ALL = np.ones(N, dtype=bool)


def _rng() -> np.random.Generator:
    return np.random.default_rng(0)


def _balanced(amplitude: float, theta_e: np.ndarray) -> np.ndarray:
    """(n, 3) balanced three-phase set."""
    return amplitude * np.c_[np.cos(theta_e), np.cos(theta_e - 2 * np.pi / 3),
                             np.cos(theta_e + 2 * np.pi / 3)]


def test_filter_alpha_is_one_step_of_the_time_constant() -> None:
    cfg = FeatureConfig()
    assert filter_alpha(cfg) == pytest.approx(1.0 - np.exp(-0.0125 / 5.0), rel=1e-15)


def test_leakage_conductance_is_the_slope_on_the_fault_point_potential() -> None:
    u = _balanced(20.0, np.linspace(0.0, 400.0, N)) + 0.3 * _rng().standard_normal((N, 3))
    v_cm = -0.5 * (u.max(axis=1) + u.min(axis=1))
    healthy = leakage_conductance(u, np.zeros(N), ALL)
    assert healthy.value == 0.0
    g = 2.0e-3  # S, from the mid-winding of phase b to the frame; plus a sensor offset
    faulty = leakage_conductance(u, g * (v_cm + 0.5 * u[:, 1]) + 0.01, ALL)
    assert faulty.value == pytest.approx(g, rel=1e-9)
    assert faulty.n_valid == N


def test_flux_deficit_is_the_relative_flux_loss() -> None:
    omega_e = 4 * 60.0 * np.sin(np.linspace(0.0, 50.0, N))
    for loss in (0.0, 0.1):
        emf = MC.flux_wb * (1.0 - loss) * omega_e
        assert flux_deficit(emf, omega_e, ALL).value == pytest.approx(loss, abs=1e-12)


def test_estimated_flux_is_clipped_and_falls_back_to_nominal() -> None:
    psi = MC.flux_wb
    assert estimated_flux(0.1) == pytest.approx(0.9 * psi, rel=1e-15)
    assert estimated_flux(float("nan")) == psi
    assert estimated_flux(0.9) == pytest.approx(0.6 * psi, rel=1e-15)
    assert estimated_flux(-0.5) == pytest.approx(1.2 * psi, rel=1e-15)


def test_flux_modulation_is_the_one_per_rev_depth() -> None:
    theta = np.linspace(0.0, 300.0, N)
    omega_e = 4 * 50.0 * (1.0 + 0.5 * np.sin(0.1 * theta))
    c, s = np.cos(theta), np.sin(theta)
    round_ = flux_modulation(MC.flux_wb * omega_e, omega_e, c, s, ALL)
    assert round_.value == pytest.approx(0.0, abs=1e-12)
    m = 0.05
    ecc = flux_modulation(MC.flux_wb * omega_e * (1.0 + m * np.cos(theta - 0.7)), omega_e, c, s,
                          ALL)
    assert ecc.value == pytest.approx(m, rel=1e-9)


def test_voltage_imbalance_is_zero_for_equal_phases() -> None:
    assert voltage_imbalance(np.full((N, 3), 50.0), ALL).value == 0.0
    rms = np.array([1.1, 1.0, 1.0])  # phase a 10 % high
    track = voltage_imbalance(np.tile(rms ** 2, (N, 1)), ALL)
    assert track.value == pytest.approx(rms.std() / rms.mean(), rel=1e-12)


def test_balanced_voltages_give_no_imbalance_through_the_step_means() -> None:
    """A balanced set at 40 Hz electrical: every 12.5 ms step holds a whole period of cos^2,
    so the per-phase mean squares about the neutral are equal and F_BDO is 0."""
    fs, n = 800.0, 40 * 800
    t = np.arange(n) / fs
    theta = 2 * np.pi * 10.0 * t  # 10 rev/s, 40 Hz electrical
    v = _balanced(30.0, 4 * theta)
    i = _balanced(2.0, 4 * theta)
    sig = {"ia": i[:, 0], "ib": i[:, 1], "ic": i[:, 2], "va": v[:, 0], "vb": v[:, 1],
           "vc": v[:, 2], "theta": theta, "x": MC.screw_radius_m * theta}
    steps = actuator_steps(sig)
    win = validity_windows(steps)
    valid = win.current_ok & win.moving
    assert valid.all()
    assert np.allclose(steps.phase_voltage_ms, 30.0 ** 2 / 2, rtol=1e-12)
    assert voltage_imbalance(steps.phase_voltage_ms, valid).value < 1e-12


def _moves(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Rod position [m] and motor speed sign of alternating up / down moves of 100 steps."""
    direction = np.where((np.arange(n) // 100) % 2 == 0, 1.0, -1.0)
    x = np.cumsum(direction) * 1e-4
    return x - x.mean(), direction


def test_friction_ratio_is_the_hysteresis_over_the_reference_plus_load() -> None:
    x, s = _moves(N)
    load, half_width = 1.2, 0.15  # N m: load torque at mid travel, friction each way
    torque = load + 30.0 * x + half_width * s  # L = a + b x, W = 2 half_width
    track = friction_ratio(torque, x, s, ALL)
    expected = 2 * half_width / (FeatureConfig().mtel_ref_torque_nm + load)
    assert track.value == pytest.approx(expected, rel=1e-9)
    # one direction only: no hysteresis
    assert np.isnan(friction_ratio(torque, x, s, s > 0).value)
    # a load below mtel_min_load_nm: no value
    assert np.isnan(friction_ratio(0.1 + half_width * s, x, s, ALL).value)


def test_screw_gap_is_the_step_between_the_flanks() -> None:
    i_q = 2.0 * np.sin(np.linspace(0.0, 60.0, N))
    nut = 0.01 * np.cos(np.linspace(0.0, 7.0, N))
    gap, compliance = 150e-6, 2e-6  # m, m per A
    x_rod = nut + 1e-5 - compliance * i_q - 0.5 * gap * np.sign(i_q)
    track = screw_gap(x_rod, nut, i_q)
    assert track.value == pytest.approx(gap, rel=1e-9)
    assert track.n_valid == np.count_nonzero(np.abs(i_q) > FeatureConfig().flank_current_a)
    one_flank = np.abs(i_q) + 0.1
    assert np.isnan(screw_gap(nut - 0.5 * gap, nut, one_flank).value)
    assert screw_gap(nut, nut, i_q).value == pytest.approx(0.0, abs=1e-15)


@pytest.mark.parametrize("r_ohm", [MC.resistance_ohm, 1.1 * MC.resistance_ohm])
def test_winding_resistance_from_a_hold(r_ohm: float) -> None:
    """At standstill v = R i: the power balance returns R, and the copper law its temperature."""
    n = 8000
    i = np.tile([1.5, -0.75, -0.75], (n, 1))
    sig = {"ia": i[:, 0], "ib": i[:, 1], "ic": i[:, 2], "va": r_ohm * i[:, 0],
           "vb": r_ohm * i[:, 1], "vc": r_ohm * i[:, 2], "theta": np.full(n, 3.0),
           "x": np.zeros(n)}
    steps = actuator_steps(sig)
    win = validity_windows(steps)
    assert win.still.all() and not win.moving.any()
    r_hat = winding_resistance(steps, win.still)
    assert r_hat == pytest.approx(r_ohm, rel=1e-12)
    expected_c = MC.ref_temp_c + (r_ohm / MC.resistance_ohm - 1.0) / MC.copper_alpha_per_k
    assert winding_temperature(r_hat) == pytest.approx(expected_c, abs=1e-9)
    assert np.isnan(winding_resistance(steps, np.zeros(steps.n_steps, dtype=bool)))
    assert np.isnan(winding_temperature(float("nan")))
