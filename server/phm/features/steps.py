"""The shared preparation of one actuator: its 800 Hz signals as 80 Hz step quantities
(:func:`actuator_steps`) and the validity windows every feature draws on
(:func:`validity_windows`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from server.vocabulary import SIGNALS

from .config import FeatureConfig, MotorConstants
from .numerics import block_mean, row_means, run_length_ok

__all__ = ["ActuatorSteps", "actuator_steps", "ValidityWindows", "validity_windows"]


def _clarke(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    alpha = (2.0 * a - b - c) / 3.0
    beta = (b - c) / np.sqrt(3.0)
    return alpha, beta


@dataclass(frozen=True)
class ActuatorSteps:
    """The 80 Hz step quantities of one actuator over one flight.

    Each array has one entry per step: the mean of the step's ``decimation`` samples of an
    800 Hz quantity (``max`` for ``electrical_hz_peak``). The first ``n_samples`` samples
    (whole steps) were used.
    """

    n_samples: int
    speed: np.ndarray  # rad/s, motor-shaft speed w
    electrical_hz_peak: np.ndarray  # Hz, p max |w| / 2 pi over the step
    electrical_hz_mean: np.ndarray  # Hz, p |mean w| / 2 pi
    current: np.ndarray  # A, current amplitude |i|
    voltage: np.ndarray  # V, voltage amplitude |v|
    current_sq: np.ndarray  # A^2, |i|^2
    power: np.ndarray  # W, v_alpha i_alpha + v_beta i_beta = (2/3) electrical power
    theta: np.ndarray  # rad, mechanical shaft angle
    cos_theta: np.ndarray  # -, cos theta
    sin_theta: np.ndarray  # -, sin theta
    x: np.ndarray  # m, LVDT rod position
    i_q: np.ndarray  # A, q-axis (torque) current
    v_q: np.ndarray  # V, q-axis voltage
    phase_voltage: np.ndarray  # (n, 3) V, u_a u_b u_c
    phase_voltage_ms: np.ndarray  # (n, 3) V^2, mean square of each phase about v0 = mean u
    common_current: np.ndarray  # A, i0 = ia + ib + ic less its flight median (sensor offsets)

    @property
    def n_steps(self) -> int:
        return int(self.speed.size)


def actuator_steps(sig: Mapping[str, np.ndarray], *, config: FeatureConfig | None = None,
                   motor: MotorConstants | None = None) -> ActuatorSteps:
    """800 Hz signals ``ia ib ic va vb vc theta x`` of one actuator -> :class:`ActuatorSteps`.

    The signals are cut to the shortest one and to whole steps; raises ``ValueError`` when
    fewer than two steps are left.
    """
    cfg = config or FeatureConfig()
    mc = motor or MotorConstants()
    d = cfg.decimation
    n = min(len(sig[k]) for k in SIGNALS) // d
    if n < 2:
        raise ValueError("flight shorter than two 80 Hz steps")
    cut = n * d

    def arr(k: str) -> np.ndarray:
        return np.asarray(sig[k][:cut], dtype=np.float64)

    def blk(a: np.ndarray) -> np.ndarray:
        return a.reshape(n, d)

    def step_mean(a: np.ndarray) -> np.ndarray:
        return row_means(blk(a))

    def step_peak(a: np.ndarray) -> np.ndarray:  # of |a|: no signed zero, any order is exact
        b = blk(a)
        peak = np.abs(b[:, 0])
        for j in range(1, d):
            np.maximum(peak, np.abs(b[:, j]), out=peak)
        return peak

    ia, ib, ic = arr("ia"), arr("ib"), arr("ic")
    va, vb, vc = arr("va"), arr("vb"), arr("vc")
    theta, x = arr("theta"), arr("x")
    i_al, i_be = _clarke(ia, ib, ic)
    v_al, v_be = _clarke(va, vb, vc)
    i0 = ia + ib + ic
    i0 = i0 - np.median(i0)  # sensor offsets of the three channels add up to a constant
    i2 = i_al * i_al + i_be * i_be  # |i|^2 [A^2]
    omega = np.gradient(theta, 1.0 / cfg.sample_rate_hz)  # rad/s, 800 Hz
    v0 = (va + vb + vc) / 3.0
    th_e = mc.pole_pairs * theta - cfg.electrical_offset_rad
    ce, se_ = np.cos(th_e), np.sin(th_e)

    w_mean = step_mean(omega)
    return ActuatorSteps(
        n_samples=cut,
        speed=w_mean,
        electrical_hz_peak=mc.pole_pairs * step_peak(omega) / (2.0 * np.pi),
        electrical_hz_mean=mc.pole_pairs * np.abs(w_mean) / (2.0 * np.pi),
        current=step_mean(np.sqrt(i2)),
        voltage=step_mean(np.sqrt(v_al * v_al + v_be * v_be)),
        current_sq=step_mean(i2),
        power=step_mean(v_al * i_al + v_be * i_be),
        theta=step_mean(theta),
        cos_theta=step_mean(np.cos(theta)),
        sin_theta=step_mean(np.sin(theta)),
        x=step_mean(x),
        i_q=step_mean(-i_al * se_ + i_be * ce),
        v_q=step_mean(-v_al * se_ + v_be * ce),
        phase_voltage=np.column_stack([step_mean(va), step_mean(vb), step_mean(vc)]),
        phase_voltage_ms=np.column_stack([step_mean((va - v0) ** 2), step_mean((vb - v0) ** 2),
                                          step_mean((vc - v0) ** 2)]),
        common_current=step_mean(i0),
    )


@dataclass(frozen=True)
class ValidityWindows:
    """Shared step masks of one actuator (80 Hz, bool)."""

    electrical_ok: np.ndarray  # electrical frequency within the transmission limit
    current_ok: np.ndarray  # ... and enough current for the current features
    moving: np.ndarray  # fast enough for a back-EMF (min_electrical_hz)
    still: np.ndarray  # in a hold of at least still_min_s
    steady_cruise: np.ndarray  # F_MTEL: steady motion (no start / stop), at cruise


def validity_windows(steps: ActuatorSteps, *, config: FeatureConfig | None = None,
                     t_amb_c: np.ndarray | None = None) -> ValidityWindows:
    """The shared validity masks of ``steps``.

    ``steady_cruise`` keeps the steps moving faster than ``mtel_min_electrical_hz`` with an
    acceleration below ``steady_accel_rad_s2`` and, when ``t_amb_c`` (800 Hz, degC) covers the
    flight, an ambient within ``cruise_band_c`` of the flight's coldest (none if the air cooled
    by less than ``cruise_min_climb_k``). It has no current floor: dropping the low-torque
    steps would drop one direction's moves under a light load.
    """
    cfg = config or FeatureConfig()
    w_mean = steps.speed
    n = steps.n_steps
    electrical_ok = steps.electrical_hz_peak < cfg.max_electrical_hz
    still = run_length_ok(np.abs(w_mean) < cfg.still_speed_rad_s,
                          max(1, int(round(cfg.still_min_s / cfg.step_s))))
    accel = np.gradient(w_mean, cfg.step_s) if n > 1 else np.zeros(n)
    steady_cruise = (electrical_ok & (steps.electrical_hz_mean > cfg.mtel_min_electrical_hz)
                     & (np.abs(accel) < cfg.steady_accel_rad_s2))
    cut = steps.n_samples
    if t_amb_c is not None and len(t_amb_c) >= cut:
        t_amb = block_mean(np.asarray(t_amb_c[:cut], dtype=np.float64), cfg.decimation)
        steady_cruise &= _cruise(t_amb, cfg)
    return ValidityWindows(
        electrical_ok=electrical_ok,
        current_ok=electrical_ok & (steps.current > cfg.min_current_a),
        moving=steps.electrical_hz_mean > cfg.min_electrical_hz,
        still=still,
        steady_cruise=steady_cruise,
    )


def _cruise(t_amb: np.ndarray, cfg: FeatureConfig) -> np.ndarray:
    """Steps within ``cruise_band_c`` of the flight's coldest air, if it climbed to a cruise."""
    if t_amb.size == 0:
        return np.zeros(0, dtype=bool)
    coldest = float(t_amb.min())
    if float(t_amb.max()) - coldest < cfg.cruise_min_climb_k:
        return np.zeros(t_amb.size, dtype=bool)
    return t_amb <= coldest + cfg.cruise_band_c
