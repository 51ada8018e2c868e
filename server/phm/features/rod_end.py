"""Rod-end play of the winglet drives, ``F_REWEAR``: the pair's lost motion across the tab's
reversals when both drive (:func:`rewear_feature`), the standby's play between stroke ends
when one stands by (:func:`standby_play_feature`); both from runs of motion at 80 Hz.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .config import FeatureConfig, MotorConstants
from .numerics import block_mean, event_track, filter_alpha
from .results import FeatureTrack

__all__ = ["rewear_feature", "standby_play_feature"]


@dataclass(frozen=True)
class _Runs:
    """Maximal runs of moving steps in one direction (80 Hz): ``mv`` the moving steps,
    ``sign`` their direction, ``run`` the run of each, ``new_run`` where a run starts."""

    mv: np.ndarray
    sign: np.ndarray
    new_run: np.ndarray
    run: np.ndarray

    @property
    def n(self) -> int:
        return int(self.run[-1]) + 1

    def pauses_s(self, step_s: float) -> np.ndarray:
        """Time from each run's last step to the next run's first [s] (n - 1)."""
        first = self.mv[self.new_run]
        last = self.mv[np.r_[np.flatnonzero(self.new_run)[1:] - 1, self.mv.size - 1]]
        return (first[1:] - last[:-1]) * step_s

    def first_k(self, mask: np.ndarray, k: int) -> np.ndarray:
        """The first ``k`` steps of ``mask`` (over ``mv``) in each run."""
        return _first_k(mask, self.new_run, self.run, k)

    def last_k(self, mask: np.ndarray, k: int) -> np.ndarray:
        """The last ``k`` steps of ``mask`` (over ``mv``) in each run."""
        rev_run = self.run[::-1]
        rev_new = np.r_[True, rev_run[1:] != rev_run[:-1]]
        return _first_k(mask[::-1], rev_new, np.cumsum(rev_new) - 1, k)[::-1]

    def means(self, sel: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per run: the count of ``sel`` steps and the mean of ``values`` (over ``mv``) on them
        (NaN without any)."""
        cnt = np.bincount(self.run, weights=sel, minlength=self.n)
        with np.errstate(invalid="ignore", divide="ignore"):
            mean = np.bincount(self.run, weights=np.where(sel, values, 0.0),
                               minlength=self.n) / cnt
        return cnt, mean


def _first_k(mask: np.ndarray, new_run: np.ndarray, run: np.ndarray, k: int) -> np.ndarray:
    c = np.cumsum(mask)
    before = np.r_[0, c[np.flatnonzero(new_run)[1:] - 1]]
    return mask & ((c - before[run]) <= k)


def _motion_runs(vel_m_s: np.ndarray, cfg: FeatureConfig) -> _Runs | None:
    """The runs of a velocity faster than ``reversal_speed_m_s``; None below two runs."""
    mv = np.flatnonzero(np.abs(vel_m_s) > cfg.reversal_speed_m_s)
    if mv.size < 2:
        return None
    sign = np.sign(vel_m_s[mv])
    new_run = np.r_[True, sign[1:] != sign[:-1]]
    runs = _Runs(mv, sign, new_run, np.cumsum(new_run) - 1)
    return runs if runs.n >= 2 else None


def _no_events() -> tuple[np.ndarray, np.ndarray]:
    return np.zeros(0, dtype=np.int64), np.zeros(0)


def _lost_motion_events(e: np.ndarray, pos_m: np.ndarray, vel_m_s: np.ndarray,
                        cfg: FeatureConfig) -> tuple[np.ndarray, np.ndarray]:
    """Lost motion of ``e`` across motion reversals of ``pos_m`` (all at 80 Hz).

    Runs are maximal sequences of moving steps with the same direction (still steps between
    them are ignored). For consecutive runs A (direction s) and B (-s), ``e`` is averaged over
    the last ``reversal_blocks`` steps of A and over the first ``reversal_blocks`` steps of B
    after ``reversal_skip_m`` of travel; the event value is ``s * (e_B - e_A)`` [m], placed at
    the first averaged step of B. Returns (event step indices, event values).
    """
    runs = _motion_runs(vel_m_s, cfg)
    if runs is None:
        return _no_events()
    mv, run = runs.mv, runs.run
    start_pos = pos_m[mv[runs.new_run]]
    ok = np.abs(pos_m[mv] - start_pos[run]) >= cfg.reversal_skip_m
    first_sel = runs.first_k(ok, cfg.reversal_blocks)
    last_sel = runs.last_k(ok, cfg.reversal_blocks)
    cnt_first, e_first = runs.means(first_sel, e[mv])
    cnt_last, e_last = runs.means(last_sel, e[mv])
    # first selected step of each run (event position)
    first_sel_step = np.full(runs.n, -1, dtype=np.int64)
    sel_idx = np.flatnonzero(first_sel)
    first_sel_step[run[sel_idx[::-1]]] = mv[sel_idx[::-1]]
    a = np.arange(runs.n - 1)
    b = a + 1
    good = ((cnt_last[a] >= 1) & (cnt_first[b] >= 1)
            & (runs.pauses_s(cfg.step_s) <= cfg.reversal_max_gap_s) & (first_sel_step[b] >= 0))
    vals = runs.sign[runs.new_run][a] * (e_first[b] - e_last[a])
    return first_sel_step[b][good], vals[good]


def rewear_feature(
    x1: np.ndarray, x2: np.ndarray, theta1: np.ndarray, theta2: np.ndarray, *,
    config: FeatureConfig | None = None, motor: MotorConstants | None = None,
) -> FeatureTrack:
    """``F_REWEAR``: lost motion of the LVDT difference ``x1 - x2`` of the winglet pair [m].

    Reversals are those of the tab, taken from the mean shaft position of the two drives.
    """
    cfg = config or FeatureConfig()
    mc = motor or MotorConstants()
    d = cfg.decimation
    r = mc.screw_radius_m
    xb1, xb2 = block_mean(x1, d), block_mean(x2, d)
    pos = r * 0.5 * (block_mean(theta1, d) + block_mean(theta2, d))
    n = min(xb1.size, xb2.size, pos.size)
    xb1, xb2, pos = xb1[:n], xb2[:n], pos[:n]
    vel = np.gradient(pos, cfg.step_s) if n > 1 else np.zeros(n)
    steps, vals = _lost_motion_events(xb1 - xb2, pos, vel, cfg)
    return event_track(n, steps, vals, filter_alpha(cfg), absolute=cfg.rewear_absolute,
                       min_events=cfg.min_events)


def standby_play_feature(
    x_active: np.ndarray, x_standby: np.ndarray, theta_active: np.ndarray,
    theta_standby: np.ndarray, iq_active: np.ndarray, *, config: FeatureConfig | None = None,
    motor: MotorConstants | None = None,
) -> FeatureTrack:
    """``F_REWEAR`` of the standby drive of an active-standby pair: the lost motion of
    ``x_active - x_standby`` between the ends of consecutive strokes of the tab [m].

    The standby is back-driven by the tab through its rod end, so once a stroke has crossed
    the play the two LVDTs differ by half of it, on the other side after a reversal: the lost
    motion is the standby's play (plus the change of the rod ends' deflection, force /
    stiffness, a few um). Taken at the stroke's end, and only where the standby's own shaft
    moves with the stroke there (the play is crossed: a worn rod end's play can exceed a short
    stroke), and where the active drive's torque (``iq_active``, 80 Hz) has the same sign at
    both ends (a one-sided hinge load keeps the active on one flank of its rod end; where the
    load changes sign the active's play would add to the lost motion).
    """
    cfg = config or FeatureConfig()
    mc = motor or MotorConstants()
    d, r = cfg.decimation, mc.screw_radius_m
    xa, xs = block_mean(x_active, d), block_mean(x_standby, d)
    pos_a, pos_s = r * block_mean(theta_active, d), r * block_mean(theta_standby, d)
    n = min(xa.size, xs.size, pos_a.size, pos_s.size, iq_active.size)
    if n < 2:
        return event_track(n, np.zeros(0, dtype=np.int64), np.zeros(0), filter_alpha(cfg))
    vel_a = np.gradient(pos_a[:n], cfg.step_s)
    vel_s = np.gradient(pos_s[:n], cfg.step_s)
    steps, vals = _stroke_end_lost_motion(xa[:n] - xs[:n], vel_a, vel_s, np.sign(iq_active[:n]),
                                          cfg)
    return event_track(n, steps, vals, filter_alpha(cfg), absolute=True,
                       min_events=cfg.min_events)


def _stroke_end_lost_motion(e: np.ndarray, vel_a: np.ndarray, vel_s: np.ndarray,
                            torque_sign: np.ndarray, cfg: FeatureConfig
                            ) -> tuple[np.ndarray, np.ndarray]:
    """Change of ``e`` between the ends of consecutive strokes of opposite direction (80 Hz):
    strokes are runs of the active shaft's motion; ``e`` and the torque sign are averaged
    over the last ``reversal_blocks`` steps of each stroke at which the standby shaft moves
    the same way; the event (at the later stroke's last such step) needs both ends, the same
    torque sign at both and a pause of at most ``reversal_max_gap_s`` between the strokes."""
    runs = _motion_runs(vel_a, cfg)
    if runs is None:
        return _no_events()
    mv, run = runs.mv, runs.run
    engaged = runs.sign * vel_s[mv] > cfg.reversal_speed_m_s
    sel = runs.last_k(engaged, cfg.reversal_blocks)
    cnt, e_end = runs.means(sel, e[mv])
    _, tq_end = runs.means(sel, torque_sign[mv])
    last_sel = np.full(runs.n, -1, dtype=np.int64)
    idx = np.flatnonzero(sel)
    last_sel[run[idx]] = mv[idx]  # the last write per run is its last selected step
    a = np.arange(runs.n - 1)
    b = a + 1
    good = ((cnt[a] >= 1) & (cnt[b] >= 1)
            & (runs.pauses_s(cfg.step_s) <= cfg.reversal_max_gap_s)
            & (np.abs(tq_end[b] - tq_end[a]) < 1.0))
    return last_sel[b][good], (e_end[b] - e_end[a])[good]
