"""Peer cross-check: our PMSM against gym-electric-motor's PMSM (upb-lea, 3.0.3).

Same parameters, same d-q voltage sequence (held for each 12 kHz step), same load. gem's own
``electrical_ode`` and ``torque`` are integrated with scipy (RK45, tight tolerances); ours is the
kernel's exact-for-frozen-speed step. i_d, i_q and speed must agree within 1 % of their range.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from sim_worker.kernel import simulate_motor
from sim_worker.params import STEP_HZ, MotorParams

gem_motors = pytest.importorskip("gym_electric_motor.physical_systems.electric_motors")


def test_healthy_pmsm_agrees_with_gym_electric_motor():
    m = MotorParams()
    b_visc, t_load = 2.0e-4, 0.05  # N m s/rad, N m
    gem = gem_motors.PermanentMagnetSynchronousMotor(motor_parameter=dict(
        p=m.pole_pairs, l_d=m.l_d_h, l_q=m.l_q_h, j_rotor=m.j_kgm2, r_s=m.r_s_ohm,
        psi_p=m.psi_pm_wb))
    # voltage profile: segments of 20 ms, both axes, including field weakening (u_d < 0)
    seg_u = [(0.0, 20.0), (0.0, 60.0), (-10.0, 60.0), (-10.0, 90.0), (5.0, 30.0), (0.0, -40.0),
             (15.0, -80.0), (0.0, 0.0), (-20.0, 50.0), (0.0, 70.0)] * 3
    steps_per_seg = int(0.02 * STEP_HZ)
    u = np.repeat(np.array(seg_u, dtype=float), steps_per_seg, axis=0)
    ours = np.zeros((u.shape[0], 3))
    simulate_motor(u, m.r_s_ohm, m.l_d_h, m.l_q_h, m.psi_pm_wb, float(m.pole_pairs), m.j_kgm2,
                   b_visc, t_load, ours)

    def rhs(_t: float, y: np.ndarray, ud: float, uq: float) -> np.ndarray:
        i_d, i_q, _eps, w = y
        d_el = gem.electrical_ode(np.array([i_d, i_q, _eps]), (ud, uq), w)
        te = gem.torque(np.array([i_d, i_q, _eps]))
        return np.array([d_el[0], d_el[1], d_el[2], (te - t_load - b_visc * w) / m.j_kgm2])

    y = np.zeros(4)
    ref = []
    dt = 1.0 / STEP_HZ
    for ud, uq in seg_u:
        t_eval = (np.arange(steps_per_seg) + 1) * dt
        sol = solve_ivp(rhs, (0.0, steps_per_seg * dt), y, args=(ud, uq), t_eval=t_eval,
                        rtol=1e-9, atol=1e-9, method="RK45")
        ref.append(sol.y[[0, 1, 3]].T)
        y = sol.y[:, -1]
    ref = np.concatenate(ref)
    for k, name in enumerate(("i_d", "i_q", "omega")):
        span = np.ptp(ref[:, k])
        err = np.max(np.abs(ours[:, k] - ref[:, k])) / span
        assert err < 0.01, f"{name}: max error {err:.3%} of its range"
    assert np.ptp(ref[:, 2]) > 100.0  # the run really spins the motor
