"""Backlash of the ball screw: ``F_MTWEAR`` (:func:`screw_gap`), the step of ``x - r theta``
between the screw's two flanks.
"""

from __future__ import annotations

import numpy as np

from .config import FeatureConfig
from .numerics import filter_alpha, filtered_track, normal_accumulators, solve_normal
from .results import FeatureTrack

__all__ = ["screw_gap"]


def _flank_combine(f: np.ndarray) -> np.ndarray:
    """Screw gap [m] from the regression of ``x - r theta`` on [1, i_q, sign(i_q)]: the rod
    sits half a gap behind the nut on either flank, ``-(gap / 2) sign(force)``."""
    coef, ok = solve_normal(f)
    return np.where(ok, -2.0 * coef[:, 2], np.nan)


def screw_gap(x_rod: np.ndarray, nut_position: np.ndarray, i_q: np.ndarray, *,
              config: FeatureConfig | None = None) -> FeatureTrack:
    """``F_MTWEAR``: gap of the screw between its two flanks [m].

    The rod (LVDT, ``x_rod`` [m]) sits behind the nut (``nut_position = r theta`` [m]) by the
    screw's compliance and half its gap on the flank the link force presses:
    ``x - r theta = c - F / k_s - (gap / 2) sign(F)``. The screw changes flank only when the
    link force changes sign, which a motion reversal under a one-sided aerodynamic load does
    not do; the motor torque (``i_q`` [A]) gives the force's sign and, to first order, its
    size. Least squares of ``x - r theta`` on ``[1, i_q, sign(i_q)]`` over the steps with
    ``|i_q| > flank_current_a`` (above the largest drag); a flight with fewer than
    ``min_flank_steps`` such steps on either flank has no value.
    """
    cfg = config or FeatureConfig()
    n = i_q.shape[0]
    flank = np.abs(i_q) > cfg.flank_current_a
    side = np.sign(i_q)
    acc = normal_accumulators(np.column_stack([np.ones(n), i_q, side]), x_rod - nut_position)
    track = filtered_track(acc, flank, _flank_combine, filter_alpha(cfg), cfg.min_valid_steps)
    if min(np.count_nonzero(flank & (side > 0)),
           np.count_nonzero(flank & (side < 0))) < cfg.min_flank_steps:
        track.value = float("nan")  # one flank only: the gap was not crossed
    return track
