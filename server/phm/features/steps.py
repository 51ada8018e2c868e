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
from .fused import STEP_ROWS, step_quantities
from .numerics import block_mean, run_length_ok

__all__ = ["ActuatorSteps", "actuator_steps", "ValidityWindows", "validity_windows"]


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

    ia, ib, ic = arr("ia"), arr("ib"), arr("ic")
    # sensor offsets of the three current channels add up to a constant: the flight median
    i0_median = float(np.median(ia + ib + ic))
    q = step_quantities(ia, ib, ic, arr("va"), arr("vb"), arr("vc"), arr("theta"), arr("x"),
                        i0_median, mc.pole_pairs, float(cfg.electrical_offset_rad),
                        float(cfg.sample_rate_hz), n, d)
    row = dict(zip(STEP_ROWS, q, strict=True))
    return ActuatorSteps(
        n_samples=cut,
        speed=row["speed"],
        electrical_hz_peak=mc.pole_pairs * row["speed_peak"] / (2.0 * np.pi),
        electrical_hz_mean=mc.pole_pairs * np.abs(row["speed"]) / (2.0 * np.pi),
        current=row["current"],
        voltage=row["voltage"],
        current_sq=row["current_sq"],
        power=row["power"],
        theta=row["theta"],
        cos_theta=row["cos_theta"],
        sin_theta=row["sin_theta"],
        x=row["x"],
        i_q=row["i_q"],
        v_q=row["v_q"],
        phase_voltage=np.column_stack([row["u_a"], row["u_b"], row["u_c"]]),
        phase_voltage_ms=np.column_stack([row["ms_a"], row["ms_b"], row["ms_c"]]),
        common_current=row["common_current"],
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
