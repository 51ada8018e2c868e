"""Friction and drag of the screw: ``F_MTEL`` (:func:`friction_ratio`), the up-down torque
hysteresis over the load at cruise, and the weight a load-independent drag carries in it
(:func:`drag_weight`, a covariate of its baseline).
"""

from __future__ import annotations

from functools import partial

import numpy as np

from .config import FeatureConfig
from .numerics import filter_alpha, filtered_track, normal_accumulators, solve_normal
from .results import FeatureTrack

__all__ = ["friction_ratio", "drag_weight"]


def _mtel_fit(f: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Load torque ``L = a + b x`` and up-down hysteresis ``W = 2 (c + d x)`` at the local
    mean position from the regression of the motor torque on ``[1, x, s, s x]`` (``s`` the
    direction of motion, ``x`` the rod position), and where the regression is solvable."""
    coef, ok = solve_normal(f, 4)
    x_mean = f[:, 1] / f[:, 0]  # accumulator of 1 * x over that of 1 * 1
    return coef[:, 0] + coef[:, 1] * x_mean, 2.0 * (coef[:, 2] + coef[:, 3] * x_mean), ok


def _mtel_combine(f: np.ndarray, ref_torque_nm: float, min_load_nm: float) -> np.ndarray:
    """Friction ratio ``W / (T_ref + |L|)`` (:func:`_mtel_fit`); NaN where ``|L| <
    min_load_nm``."""
    load, width, ok = _mtel_fit(f)
    return np.where(ok & (np.abs(load) >= min_load_nm),
                    width / (ref_torque_nm + np.abs(load)), np.nan)


def _drag_weight_combine(f: np.ndarray, ref_torque_nm: float, min_load_nm: float
                         ) -> np.ndarray:
    """``1 / (T_ref + |L|)`` of the same regression: the weight a load-independent drag
    carries in the friction ratio; NaN where the ratio has no value."""
    load, _, ok = _mtel_fit(f)
    return np.where(ok & (np.abs(load) >= min_load_nm), 1.0 / (ref_torque_nm + np.abs(load)),
                    np.nan)


def friction_ratio(torque: np.ndarray, x_rod: np.ndarray, speed: np.ndarray,
                   valid: np.ndarray, *, config: FeatureConfig | None = None) -> FeatureTrack:
    """``F_MTEL``: friction ratio of the screw ``W / (T_ref + |L|)`` [-] at cruise.

    Moving against the load torque L the motor gives ``|L| / eta_d + T_c``, moving with it
    ``|L| eta_b - T_c``: at one deflection the torque of an upward and a downward move differ
    by the friction both ways, ``W = |L| (1 / eta_d - eta_b) + 2 T_c``, and their mean is about
    L. Aged grease lowers the efficiencies and raises the drag ``T_c``: W grows on both counts.
    The hinge load at cruise is the paper's expected aerodynamic load, linear in the
    deflection, ``F = -(k x + bias)``, with the flight's unknown dynamic-pressure scale and
    offset: ``L = a + b x``, identified with the friction from the motor ``torque`` [N m]
    itself by least squares on ``[1, x, s, s x]`` (``x`` the rod position ``x_rod`` [m] about
    its mean over ``valid`` steps, ``s`` the sign of the motor ``speed``) over ``valid``
    steps. On a healthy drive ``W = c0 + k0 |L|``, so the ratio with ``T_ref = c0 / k0``
    (``mtel_ref_torque_nm``) is k0 whatever the load. NaN value with fewer than
    ``mtel_min_steps`` valid steps in either direction (no hysteresis seen).
    """
    cfg = config or FeatureConfig()
    acc, s_dir = _mtel_accumulators(torque, x_rod, speed, valid)
    track = filtered_track(
        acc, valid,
        partial(_mtel_combine, ref_torque_nm=cfg.mtel_ref_torque_nm,
                min_load_nm=cfg.mtel_min_load_nm),
        filter_alpha(cfg), cfg.min_valid_steps)
    n_up = int(np.count_nonzero(valid & (s_dir > 0)))
    if min(n_up, int(np.count_nonzero(valid)) - n_up) < cfg.mtel_min_steps:
        track.value = float("nan")  # one direction barely seen: no hysteresis
    return track


def _mtel_accumulators(torque: np.ndarray, x_rod: np.ndarray, speed: np.ndarray,
                       valid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The per-step normal-equation accumulators of ``F_MTEL``'s regression, and the
    direction of motion."""
    n = torque.shape[0]
    x_rel_mm = 1e3 * (x_rod - (x_rod[valid].mean() if valid.any() else 0.0))
    s_dir = np.sign(speed)
    return normal_accumulators(np.column_stack([np.ones(n), x_rel_mm, s_dir,
                                                s_dir * x_rel_mm]), torque), s_dir


def drag_weight(torque: np.ndarray, x_rod: np.ndarray, speed: np.ndarray, valid: np.ndarray,
                *, config: FeatureConfig | None = None) -> float:
    """``1 / (T_ref + |L|)`` [1/(N m)] over the flight's cruise moves, ``L`` the load torque
    ``F_MTEL``'s regression identifies (the mean of the up and down torques: the friction
    cancels to first order, so an aged grease barely moves it): how much a load-independent
    drag weighs in the friction ratio. A winglet drive back-drives its attached standby, whose
    drag is such a term, so its healthy ratio falls as the hinge load grows (a test station's
    load scale); the baseline of ``F_MTEL`` takes this as a covariate. NaN where the ratio
    has no value."""
    cfg = config or FeatureConfig()
    idx = np.flatnonzero(valid)
    if idx.size < cfg.min_valid_steps:
        return float("nan")
    acc, _ = _mtel_accumulators(torque, x_rod, speed, valid)
    with np.errstate(divide="ignore", invalid="ignore"):
        return float(_drag_weight_combine(acc[idx].mean(axis=0, keepdims=True),
                                          cfg.mtel_ref_torque_nm, cfg.mtel_min_load_nm)[0])
