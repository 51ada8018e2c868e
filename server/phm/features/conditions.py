"""Temperature and operating conditions: the winding resistance from still steps and the
winding temperature it gives, an actuator's design load and speed over the flight, and the
flight's ambient temperatures (what the baselines are conditioned on).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from .config import FeatureConfig, MotorConstants
from .steps import ActuatorSteps

__all__ = ["winding_resistance", "resistance_or_nominal", "winding_temperature", "step_conditions",
           "operating_conditions"]


def winding_resistance(steps: ActuatorSteps, still: np.ndarray, *,
                       config: FeatureConfig | None = None) -> float:
    """Phase resistance [Ohm] from the power balance ``p = R |i|^2`` of still steps carrying
    at least twice ``min_current_a``; NaN with fewer than ``min_r_estimate_blocks`` steps."""
    cfg = config or FeatureConfig()
    r_sel = still & (steps.current > 2 * cfg.min_current_a)
    if np.count_nonzero(r_sel) >= cfg.min_r_estimate_blocks:
        return float(steps.power[r_sel].sum() / steps.current_sq[r_sel].sum())
    return float("nan")


def resistance_or_nominal(r_hat: float, mc: MotorConstants) -> float:
    return r_hat if np.isfinite(r_hat) and r_hat > 0 else mc.resistance_ohm


def winding_temperature(r_hat: float, motor: MotorConstants | None = None) -> float:
    """Winding temperature [degC] from the copper's resistance law; NaN without an estimate
    (a non-positive estimate reads as the nominal resistance)."""
    mc = motor or MotorConstants()
    if not np.isfinite(r_hat):
        return float("nan")
    r_use = resistance_or_nominal(r_hat, mc)
    return float(mc.ref_temp_c + (r_use / mc.resistance_ohm - 1.0) / mc.copper_alpha_per_k)


def step_conditions(steps: ActuatorSteps, aero_gradient_n_per_m: float, aero_bias_n: float,
                    r_hat: float, motor: MotorConstants | None) -> dict[str, float]:
    """An actuator's operating conditions over the flight: design aero load and shaft speed
    (RMS), winding temperature from the resistance estimate (NaN without one)."""
    load_exp = -(aero_gradient_n_per_m * steps.x + aero_bias_n)  # N, design aero load
    return {"temp_winding_est_c": winding_temperature(r_hat, motor),
            "load_rms_n": float(np.sqrt(np.mean(load_exp ** 2))),
            "speed_rms_rad_s": float(np.sqrt(np.mean(steps.speed ** 2)))}


def operating_conditions(channels: Mapping[str, np.ndarray]) -> dict[str, float]:
    """Flight-level conditions from the optional ``T_amb`` channel [degC] (NaN if absent).

    ``temp_ground_c`` is the largest ambient temperature of the flight (on ground, before the
    climb to cruise), ``temp_mean_c`` its mean.
    """
    t_amb = channels.get("T_amb")
    if t_amb is None or len(t_amb) == 0:
        return {"temp_ground_c": float("nan"), "temp_mean_c": float("nan")}
    t = np.asarray(t_amb, dtype=np.float64)
    return {"temp_ground_c": float(np.max(t)), "temp_mean_c": float(np.mean(t))}
