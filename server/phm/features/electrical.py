"""The electrical and magnetic features of the motor (80 Hz arrays in, :class:`FeatureTrack`
out): ``F_TTS`` (:func:`leakage_conductance`), ``F_DMD`` (:func:`flux_deficit`, with
:func:`estimated_flux`), ``F_SE`` (:func:`flux_modulation`) and ``F_BDO``
(:func:`voltage_imbalance`).
"""

from __future__ import annotations

from functools import partial

import numpy as np

from .config import FeatureConfig, MotorConstants
from .numerics import (
    filter_alpha,
    filtered_track,
    normal_accumulators,
    row_max,
    row_min,
    solve_normal,
)
from .results import FeatureTrack

__all__ = ["leakage_conductance", "flux_deficit", "estimated_flux", "flux_modulation",
           "voltage_imbalance"]


def _tts_combine(f: np.ndarray) -> np.ndarray:
    """Largest per-phase least-squares slope of i0 on x_k (filtered means) [S]."""
    y, x, xy, xx = f[:, 0:1], f[:, 1:4], f[:, 4:7], f[:, 7:10]
    return row_max((xy - x * y) / (xx - x * x))


def leakage_conductance(phase_voltage: np.ndarray, common_current: np.ndarray,
                        valid: np.ndarray, *, config: FeatureConfig | None = None
                        ) -> FeatureTrack:
    """``F_TTS``: leakage conductance of the winding to the frame [S].

    A turn-to-turn short damages the insulation and opens a path from the mid-winding of the
    faulty phase to the frame: the common-node current is ``i0 = G (v_cm + u_k / 2)``, with the
    common-mode voltage of a min-max (space-vector) modulator ``v_cm = -(max u + min u) / 2``
    reconstructed from the three measured phase voltages ``phase_voltage`` (n, 3) [V]. Per
    phase k, the least-squares slope of ``common_current`` (n,) [A] on ``x_k = v_cm + u_k / 2``
    (with intercept: sensor offsets) estimates G; the feature is the largest of the three
    slopes (the faulty phase is not known a priori). A healthy motor gives 0 +- noise whatever
    the operating point.
    """
    cfg = config or FeatureConfig()
    u_b = phase_voltage
    v_cm_b = -0.5 * (row_max(u_b) + row_min(u_b))
    x_tts = v_cm_b[:, np.newaxis] + 0.5 * u_b  # (n, 3) [V]
    i0_b = common_current
    acc = np.column_stack([i0_b, x_tts, x_tts * i0_b[:, np.newaxis], x_tts * x_tts])
    return filtered_track(acc, valid, _tts_combine, filter_alpha(cfg), cfg.min_valid_steps)


def _dmd_combine(f: np.ndarray, psi_nom: float) -> np.ndarray:
    return 1.0 - (f[:, 0] / f[:, 1]) / psi_nom


def flux_deficit(emf: np.ndarray, omega_e: np.ndarray, valid: np.ndarray, *,
                 config: FeatureConfig | None = None, motor: MotorConstants | None = None
                 ) -> FeatureTrack:
    """``F_DMD``: ``1 - psi_hat / psi_nom`` [-], the relative loss of magnet flux.

    ``v_q = R i_q + L di_q/dt + omega_e psi`` (``i_d = 0`` control, ``L_d = L_q``): least
    squares of the back-EMF ``emf = v_q - R_hat i_q`` [V] on the electrical speed ``omega_e``
    [rad/s] over ``valid`` steps, ``psi_hat = sum(e w) / sum(w^2)``. The current needed per
    unit torque scales with ``1 / psi``, so F_DMD is also the relative excess of phase current
    over the current expected with the nominal flux.
    """
    cfg = config or FeatureConfig()
    mc = motor or MotorConstants()
    return filtered_track(np.column_stack([emf * omega_e, omega_e * omega_e]), valid,
                          partial(_dmd_combine, psi_nom=mc.flux_wb), filter_alpha(cfg),
                          cfg.min_valid_steps)


def estimated_flux(f_dmd: float, motor: MotorConstants | None = None) -> float:
    """Magnet flux [Wb] of the flight from its ``F_DMD`` value, kept within 0.6 to 1.2 times
    the nominal flux (the nominal flux when F_DMD has no value)."""
    mc = motor or MotorConstants()
    psi_nom = mc.flux_wb
    psi_hat = psi_nom * (1.0 - f_dmd)
    if not np.isfinite(psi_hat):
        psi_hat = psi_nom
    return float(np.clip(psi_hat, 0.6 * psi_nom, 1.2 * psi_nom))


def _se_combine(f: np.ndarray) -> np.ndarray:
    """Relative 1/rev modulation from the 3x3 normal equations (6 upper entries, 3 rhs)."""
    coef, ok = solve_normal(f)
    out = np.hypot(coef[:, 1], coef[:, 2]) / coef[:, 0]
    return np.where(ok, out, np.nan)


def flux_modulation(emf: np.ndarray, omega_e: np.ndarray, cos_theta: np.ndarray,
                    sin_theta: np.ndarray, valid: np.ndarray, *,
                    config: FeatureConfig | None = None) -> FeatureTrack:
    """``F_SE``: relative 1/rev modulation of the magnet flux [-].

    Static eccentricity modulates the flux linkage ``psi (1 + m cos(theta - phi))``; the q-axis
    back-EMF ``emf = v_q - R_hat i_q = omega_e psi(theta)`` shows it whatever the load and the
    acceleration (unlike the current). Weighted least squares of ``emf`` on ``omega_e [1,
    cos theta, sin theta]`` (the step means ``cos_theta``, ``sin_theta`` of the mechanical
    angle) over ``valid`` steps; ``F_SE = hypot(b, c) / a``.
    """
    cfg = config or FeatureConfig()
    xs = np.column_stack([omega_e, omega_e * cos_theta, omega_e * sin_theta])
    acc = normal_accumulators(xs, emf)
    return filtered_track(acc, valid, _se_combine, filter_alpha(cfg), cfg.min_valid_steps)


def _bdo_combine(f: np.ndarray) -> np.ndarray:
    rms = np.sqrt(np.maximum(f, 0.0))
    return rms.std(axis=1) / rms.mean(axis=1)


def voltage_imbalance(phase_voltage_ms: np.ndarray, valid: np.ndarray, *,
                      config: FeatureConfig | None = None) -> FeatureTrack:
    """``F_BDO``: imbalance of the three phase-voltage RMS values, std / mean over the phases
    [-], from the per-step mean squares ``phase_voltage_ms`` (n, 3) [V^2] about the neutral.
    A balanced three-phase set gives 0.
    """
    cfg = config or FeatureConfig()
    return filtered_track(phase_voltage_ms, valid, _bdo_combine, filter_alpha(cfg),
                          cfg.min_valid_steps)
