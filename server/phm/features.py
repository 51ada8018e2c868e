"""Health features of the EMAs (paper Table 1), vectorised over a whole flight.

Time base and units
-------------------
* Input: plain arrays sampled at ``sample_rate_hz`` (800 Hz), SI units: phase currents [A],
  phase voltages [V], motor-shaft angle ``theta`` [rad, unwrapped, mechanical], LVDT rod
  position ``x`` [m]. Keys of a flight mapping follow flight-log format v1 (``"WL1.ia"``, ...,
  optional ``"T_amb"`` [degC]).
* 800 Hz -> 80 Hz: block means of ``decimation`` (10) samples; one *step* is one block
  (12.5 ms). A trailing partial block is dropped.
* Frames: amplitude-invariant Clarke transform (``|i|`` is the peak phase-current amplitude
  of a balanced set); the zero-sequence (common-node) current is ``i0 = ia + ib + ic``.
  No feature needs the resolver's electrical alignment: only magnitudes, power and the
  mechanical angle are used.

Every feature is built the same way: per 80 Hz step a few *accumulators* (e.g. numerator and
denominator of a ratio) and a validity mask; an exponential filter (first-order IIR with time
constant ``ewma_tau_s`` of valid time, ``scipy.signal.lfilter``) runs over the valid steps only;
the feature at a step is a function of the filtered accumulators (a ratio of local means, which
is far more robust than filtering a ratio). The per-flight value is the same function of the
whole-flight means of the accumulators over valid steps (the filter's infinite-memory limit);
the dispersion is the standard deviation of the filtered 80 Hz series over valid steps.

Layout
------
:func:`actuator_features` composes the shared preparation and one function per feature:

* :func:`actuator_steps` (800 Hz -> 80 Hz step quantities, :class:`ActuatorSteps`),
  :func:`validity_windows` (:class:`ValidityWindows`), :func:`winding_resistance` and
  :func:`filter_alpha` (the exponential filter's coefficient);
* :func:`leakage_conductance` (``F_TTS``), :func:`flux_deficit` (``F_DMD``, with
  :func:`estimated_flux`), :func:`flux_modulation` (``F_SE``), :func:`voltage_imbalance`
  (``F_BDO``), :func:`friction_ratio` (``F_MTEL``), :func:`screw_gap` (``F_MTWEAR``).

Each feature function takes the 80 Hz arrays its formula needs, so it can be called on its own.

Features (formulas and validity rules are in ``docs/FEATURES.md``):

``F_TTS``  leakage conductance winding-to-frame [S]: slope of the common-node current on the
           fault-point potential ``v_cm + u_k / 2`` (largest over the phases).
``F_DMD``  relative excess of current over the current expected with the nominal flux,
           ``1 - psi_hat / psi_nom`` [-], psi_hat from the q-axis voltage balance; moving
           current-valid steps.
``F_SE``   relative 1/rev modulation of the flux from the q-axis back-EMF (mechanical angle)
           [-]; moving steps.
``F_BDO``  imbalance of the three phase-voltage RMS values (std / mean over phases) [-].
``F_MTEL`` friction ratio of the screw at cruise [-]: the torque hysteresis between moving
           up and down at the same deflection over the load torque plus a reference torque,
           ``W / (T_ref + |L|)``; constant on a healthy drive whatever the load, grows with
           the efficiency loss and the drag of aged grease.
``F_MTWEAR`` screw gap [m]: the step of ``x - r theta`` between the two flanks of the screw,
           the flank read from the sign of the motor torque (``i_q``).
``F_REWEAR`` rod-end play of a winglet drive [m]: on a flight it stands by, the lost motion of
           ``x_active - x_standby`` between stroke ends (:func:`standby_play_feature`); with
           both drives active, the pair's lost motion ``x_WL1 - x_WL2`` across reversals.
"""

from __future__ import annotations

from collections.abc import Callable, Collection, Mapping
from dataclasses import dataclass, field
from functools import partial

import numpy as np
from scipy.signal import lfilter

from server.vocabulary import (
    ACTUATOR_FEATURES,
    POSITIONS,
    REWEAR_FEATURE,
    SIGNALS,
    WINGLET_PAIR,
    position_features,
)

from .signal_quality import flight_quality

__all__ = [
    "FEATURE_VERSION",
    "FEATURE_SENSORS",
    "ACTUATOR_FEATURES",
    "POSITIONS",
    "WINGLET_PAIR",
    "AIRCRAFT_FEATURES",
    "CONDITION_NAMES",
    "SIGNALS",
    "MotorConstants",
    "FeatureConfig",
    "FeatureTrack",
    "FeatureSummary",
    "FlightFeatures",
    "ActuatorSteps",
    "ValidityWindows",
    "block_mean",
    "exp_filter",
    "filter_alpha",
    "actuator_steps",
    "validity_windows",
    "winding_resistance",
    "winding_temperature",
    "leakage_conductance",
    "flux_deficit",
    "estimated_flux",
    "flux_modulation",
    "voltage_imbalance",
    "friction_ratio",
    "screw_gap",
    "actuator_features",
    "rewear_feature",
    "standby_play_feature",
    "operating_conditions",
    "standby_drive",
    "flight_features",
]

#: bumped whenever a feature formula or validity changes (invalidates cached campaign
#: features); the history of the bumps is in docs/TUNING.md
FEATURE_VERSION = "features/10"
#: the sensors each generic feature reads: its own actuator's, both winglet drives' for
#: F_REWEAR. Every feature's validity windows read the motor speed, hence the resolver
FEATURE_SENSORS: dict[str, tuple[str, ...]] = {
    "F_TTS": ("current", "voltage", "resolver"), "F_DMD": ("current", "voltage", "resolver"),
    "F_SE": ("current", "voltage", "resolver"), "F_BDO": ("current", "voltage", "resolver"),
    "F_MTEL": ("current", "resolver", "lvdt"), "F_MTWEAR": ("current", "resolver", "lvdt"),
    "F_REWEAR": ("resolver", "lvdt"),
}
#: the 20 feature names of one aircraft, ``"<position>.<feature>"``: six per drive, and the
#: rod-end play of each winglet drive
AIRCRAFT_FEATURES: tuple[str, ...] = tuple(
    f"{p}.{f}" for p in POSITIONS for f in position_features(p))
#: per-actuator operating conditions used by the baselines
CONDITION_NAMES: tuple[str, ...] = (
    "temp_ground_c", "temp_mean_c", "load_rms_n", "speed_rms_rad_s", "temp_winding_est_c",
    "mtel_drag_weight_per_nm")


@dataclass(frozen=True)
class MotorConstants:
    """Nominal EMA constants the feature maths assumes (the design values, not the truth)."""

    pole_pairs: int = 4  # -
    resistance_ohm: float = 1.86  # Ohm, phase, at ref_temp_c
    inductance_h: float = 3.72e-3  # H
    flux_wb: float = 0.061  # Wb, permanent-magnet flux linkage (peak, amplitude-invariant)
    lead_m: float = 0.005  # m per motor revolution (ball screw)
    ref_temp_c: float = 20.0  # degC, temperature of resistance_ohm
    copper_alpha_per_k: float = 0.00393  # 1/K

    @property
    def screw_radius_m(self) -> float:
        """r = lead / 2 pi [m/rad]."""
        return self.lead_m / (2.0 * np.pi)

    @property
    def torque_constant_nm_per_a(self) -> float:
        """1.5 p psi [Nm per A of peak current amplitude]."""
        return 1.5 * self.pole_pairs * self.flux_wb


def _default_aero() -> dict[str, float]:
    # a winglet drive, when active, carries the tab's whole hinge load: both of its shares
    return {"WL1": 8.0e4, "WL2": 8.0e4, "WT": 6.0e4}


def _default_aero_bias() -> dict[str, float]:
    return {"WL1": 500.0, "WL2": 500.0, "WT": 300.0}


@dataclass(frozen=True)
class FeatureConfig:
    """Windows, thresholds and filter of the feature extraction (all SI).

    Each field states its unit and why it has its value; the measurements behind the tuned
    values (and the alternatives scored) are tabled in ``docs/TUNING.md``. ``repr`` of this
    class is part of the campaign feature-cache key (:func:`server.campaigns.feature_config_key`).
    """

    #: Hz, rate of the flight-log channels (format v1)
    sample_rate_hz: float = 800.0
    #: samples per step: every feature is computed on 80 Hz block means (12.5 ms steps)
    decimation: int = 10
    #: Hz electrical, transmission limit of the current features: faster steps are skipped
    max_electrical_hz: float = 80.0
    #: Hz electrical, "moving" for F_DMD / F_SE (they read the back-EMF, which vanishes with
    #: the speed) and F_BDO (a hold's DC voltages depend on where the rotor stopped)
    min_electrical_hz: float = 2.0
    #: rad/s, |mean motor speed| of a step below which it is still (no back-EMF: the power
    #: balance is p = R |i|^2, used for the resistance estimate)
    still_speed_rad_s: float = 0.5
    #: s, a still window lasts at least this, so that a move passing through zero speed (a
    #: reversal) is not taken for a hold
    still_min_s: float = 0.3
    #: A (amplitude), least current of a step for F_DMD / F_SE / F_BDO (twice this for the
    #: resistance estimate): below it the current is of the order of the sensor offsets
    min_current_a: float = 0.3
    #: V (amplitude), F_BDO needs this much voltage for its per-phase RMS ratio
    min_voltage_v: float = 0.5
    #: s of valid time, time constant of the exponential filter of the 80 Hz tracks
    ewma_tau_s: float = 5.0
    #: design aero model of the rod load at cruise dynamic pressure, F = -(k x + bias) (+x is
    #: extension): hinge-load gradient k [N/m of rod travel] and bias [N], per position
    aero_gradient_n_per_m: Mapping[str, float] = field(default_factory=_default_aero)
    aero_bias_n: Mapping[str, float] = field(default_factory=_default_aero_bias)
    #: K, F_MTEL only where T_amb is within this of the flight's coldest air: its cruise, where
    #: the dynamic pressure is the design one (the hinge load linear in the deflection). Read
    #: from the flight's own coldest air, so a warmer or colder day (an ISA deviation, a test
    #: station's ambient offset) moves the window with the air instead of emptying it
    cruise_band_c: float = 3.0
    #: K, the air must cool by at least this from the flight's warmest to its coldest for the
    #: flight to have a cruise at all (3 km of climb at the standard lapse rate); a run on the
    #: ground has no F_MTEL
    cruise_min_climb_k: float = 20.0
    #: N m, F_MTEL's reference torque T_ref = c0 / k0 of the healthy hysteresis line
    #: W = c0 + k0 |L| measured on healthy cruise flights, so that W / (T_ref + |L|) is k0
    #: whatever the load. Physics alone gives c0 = 2 x 0.04 N m drag and k0 =
    #: (1/eta_d - eta_b) / mean = 0.22, T_ref 0.36 N m; the measured drag is larger (link
    #: damping, the tab's force share)
    mtel_ref_torque_nm: float = 0.47
    #: rad/s^2 of motor acceleration (80 Hz) above which a step is a start or stop of a move,
    #: not the steady motion F_MTEL compares
    steady_accel_rad_s2: float = 30.0
    #: steady cruise steps F_MTEL needs in each direction (0.75 s): with one direction barely
    #: seen there is no hysteresis to measure
    mtel_min_steps: int = 60
    #: N m, F_MTEL needs a cruise load torque |L| of at least this: under a lighter load the
    #: ratio rests on the drag alone and its flight-to-flight scatter doubles
    mtel_min_load_nm: float = 0.3
    #: Hz electrical, "moving" for F_MTEL: the friction hysteresis needs no back-EMF, and the
    #: slow moves of long flights (reference cycle stretched over more time) still count
    mtel_min_electrical_hz: float = 1.0
    #: still steps needed to trust the resistance estimate (else the nominal resistance)
    min_r_estimate_blocks: int = 20
    #: steps a flight needs for a feature value (else NaN)
    min_valid_steps: int = 40
    #: reversals a flight needs for F_REWEAR (else NaN)
    min_events: int = 3
    #: A of |i_q| above which the motor torque tells the flank the screw bears on: above the
    #: largest drag it may have to overcome (Coulomb 0.04 N m x 1.3 breakaway x 3 with aged
    #: grease = 0.16 N m = 0.43 A at 0.366 N m/A), so the torque sign is the link-force sign
    flank_current_a: float = 0.6
    #: steps a flight needs on each flank for F_MTWEAR (0.5 s; else NaN): fewer let single
    #: outliers through
    min_flank_steps: int = 40
    #: rad, resolver zero to d axis (drive commissioning)
    electrical_offset_rad: float = 0.0
    #: m/s of r*omega, "moving" for reversals
    reversal_speed_m_s: float = 1.0e-3
    #: m of travel skipped after a reversal, more than the largest gap to be measured
    reversal_skip_m: float = 0.5e-3
    #: steps averaged on each side of a reversal
    reversal_blocks: int = 4
    #: s, longest stop between the two runs of a reversal
    reversal_max_gap_s: float = 3.0
    #: F_REWEAR uses |lost motion|: which side of the gap the rod end starts on is unknown
    rewear_absolute: bool = True

    def __post_init__(self) -> None:
        if self.decimation < 1 or self.sample_rate_hz <= 0 or self.ewma_tau_s <= 0:
            raise ValueError("decimation, sample_rate_hz and ewma_tau_s must be positive")

    @property
    def step_s(self) -> float:
        """Duration of one 80 Hz step [s]."""
        return self.decimation / self.sample_rate_hz


@dataclass
class FeatureTrack:
    """One feature over one flight at 80 Hz.

    ``series[k]`` is the filtered feature at step k (NaN before the first valid step, held
    between valid steps); ``valid[k]`` says whether step k contributed.
    """

    series: np.ndarray  # (n_steps,)
    valid: np.ndarray  # (n_steps,) bool
    value: float  # flight value (NaN if no valid step)
    dispersion: float  # std of the filtered series over valid steps
    n_valid: int

    def summary(self) -> FeatureSummary:
        return FeatureSummary(self.value, self.dispersion, self.n_valid)


@dataclass(frozen=True)
class FeatureSummary:
    """Per-flight summary of one feature."""

    value: float
    dispersion: float
    n_valid: int

    def to_dict(self) -> dict[str, float | int]:
        return {"value": self.value, "dispersion": self.dispersion, "n_valid": self.n_valid}


@dataclass
class FlightFeatures:
    """All 20 features of one flight plus the operating conditions of each actuator."""

    summaries: dict[str, FeatureSummary]  # AIRCRAFT_FEATURES -> summary
    conditions: dict[str, dict[str, float]]  # position -> CONDITION_NAMES -> value
    tracks: dict[str, FeatureTrack] | None = None  # only when asked for
    #: channel -> signal-quality figures (:mod:`server.phm.signal_quality`); empty when the
    #: features were stored without them
    quality: dict[str, dict[str, float]] = field(default_factory=dict)

    def values(self) -> dict[str, float]:
        return {k: s.value for k, s in self.summaries.items()}

    def to_dict(self) -> dict[str, object]:
        return {"summaries": {k: s.to_dict() for k, s in self.summaries.items()},
                "conditions": self.conditions, "quality": self.quality}


# --------------------------------------------------------------------------------------------
# building blocks
# --------------------------------------------------------------------------------------------


def block_mean(a: np.ndarray, decimation: int) -> np.ndarray:
    """Means of consecutive blocks of ``decimation`` samples along axis 0.

    A trailing partial block is dropped.
    """
    a = np.asarray(a, dtype=np.float64)
    n = a.shape[0] // decimation
    if a.ndim == 1:
        return _row_means(a[: n * decimation].reshape(n, decimation))
    return a[: n * decimation].reshape((n, decimation) + a.shape[1:]).mean(axis=1)


_PAIRWISE_LANES = 8  # NumPy's pairwise sum of a short row: 8 partial sums, then the rest
_PAIRWISE_BLOCK = 128  # ... up to this many elements (longer rows are split)


def _row_means(blocks: np.ndarray) -> np.ndarray:
    """``blocks.mean(axis=1)`` of an (n, d) array, to the bit, in column operations.

    NumPy sums each row with one call of its pairwise sum (rows under 8 elements in turn, else
    8 partial sums combined as a tree, then the remaining elements in turn) added onto 0.0,
    then divides by d. A call per 10-sample row costs more than the additions; the same
    additions in the same order, column by column, cost a third as much.
    """
    d = blocks.shape[1]
    if d == 0 or d > _PAIRWISE_BLOCK:
        return blocks.mean(axis=1)
    col = [blocks[:, j] for j in range(d)]
    if d < _PAIRWISE_LANES:
        total = col[0].copy()
        for c in col[1:]:
            total += c
    else:
        whole = d - d % _PAIRWISE_LANES
        r = col[:_PAIRWISE_LANES]
        for i in range(_PAIRWISE_LANES, whole, _PAIRWISE_LANES):
            r = [r[j] + col[i + j] for j in range(_PAIRWISE_LANES)]
        total = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]))
        for c in col[whole:]:
            total += c
    total += 0.0  # onto 0.0: a sum of negative zeros is +0.0, as NumPy's
    total /= d
    return total


def _row_max(a: np.ndarray) -> np.ndarray:
    """``a.max(axis=1)`` of a narrow (n, k) array, to the bit, column by column: NumPy's
    reduction over a row keeps the running maximum unless it is NaN or the next value is not
    below it (of two equal values, signed zeros, the later)."""
    acc = a[:, 0]
    for j in range(1, a.shape[1]):
        b = a[:, j]
        acc = np.where((acc > b) | np.isnan(acc), acc, b)
    return acc


def _row_min(a: np.ndarray) -> np.ndarray:
    """``a.min(axis=1)`` of a narrow (n, k) array, to the bit (see :func:`_row_max`)."""
    acc = a[:, 0]
    for j in range(1, a.shape[1]):
        b = a[:, j]
        acc = np.where((acc < b) | np.isnan(acc), acc, b)
    return acc


def exp_filter(x: np.ndarray, alpha: float) -> np.ndarray:
    """Exponential filter ``y[k] = alpha x[k] + (1 - alpha) y[k-1]`` along axis 0, ``y[-1] = x[0]``.

    Vectorised with :func:`scipy.signal.lfilter`; works on (n,) or (n, m) arrays.
    """
    x = np.asarray(x, dtype=np.float64)
    if x.shape[0] == 0:
        return x.copy()
    zi = ((1.0 - alpha) * x[0])[np.newaxis, ...] if x.ndim > 1 else np.array([(1 - alpha) * x[0]])
    y, _ = lfilter([alpha], [1.0, -(1.0 - alpha)], x, axis=0, zi=zi)
    return y


def _track(acc: np.ndarray, valid: np.ndarray, combine: Callable[[np.ndarray], np.ndarray],
           alpha: float, min_valid: int = 1) -> FeatureTrack:
    """Filter accumulators ``acc`` (n, m) over valid steps and combine them into a feature."""
    n = acc.shape[0]
    series = np.full(n, np.nan)
    idx = np.flatnonzero(valid)
    if idx.size == 0:
        return FeatureTrack(series, valid, float("nan"), float("nan"), 0)
    acc_valid = acc[idx]
    filt = exp_filter(acc_valid, alpha)
    with np.errstate(divide="ignore", invalid="ignore"):
        f_valid = combine(filt)
        value = float(combine(acc_valid.mean(axis=0, keepdims=True))[0])
    if idx.size < min_valid:
        value = float("nan")
    series[idx] = f_valid
    # hold the last valid value between valid steps
    last = np.maximum.accumulate(np.where(valid, np.arange(n), -1))
    held = last >= 0
    series[held] = series[last[held]]
    finite = f_valid[np.isfinite(f_valid)]
    disp = float(np.std(finite)) if finite.size > 1 else float("nan")
    return FeatureTrack(series, valid, value, disp, int(idx.size))


def _ratio(filt: np.ndarray) -> np.ndarray:
    return filt[:, 0] / filt[:, 1]


def _run_length_ok(mask: np.ndarray, min_len: int) -> np.ndarray:
    """Steps of ``mask`` that belong to a run of at least ``min_len`` consecutive True."""
    if min_len <= 1 or mask.size == 0:
        return mask.copy()
    m = mask.astype(np.int8)
    edges = np.diff(np.r_[0, m, 0])
    starts = np.flatnonzero(edges == 1)
    ends = np.flatnonzero(edges == -1)
    lengths = ends - starts
    run_len = np.zeros(mask.size + 1, dtype=np.int64)
    np.add.at(run_len, starts, lengths)
    np.add.at(run_len, ends, -lengths)
    return mask & (np.cumsum(run_len)[:-1] >= min_len)


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


def _normal_accumulators(xs: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Per-step terms of the k x k normal equations of ``y`` on ``xs`` (n, k): the upper
    triangle of ``xs xs'`` (row by row) then the k entries of ``xs y`` (see
    :func:`_solve_normal`)."""
    n, k = xs.shape
    iu = np.triu_indices(k)
    out = np.empty((n, iu[0].size + k))
    for c, (i, j) in enumerate(zip(iu[0], iu[1], strict=True)):  # the upper triangle only
        np.multiply(xs[:, i], xs[:, j], out=out[:, c])
    np.multiply(xs, y[:, np.newaxis], out=out[:, iu[0].size:])
    return out


def _normal_matrix(f: np.ndarray, k: int) -> np.ndarray:
    """The symmetric (n, k, k) matrices of (filtered) normal-equation accumulators."""
    iu = np.triu_indices(k)
    a = np.zeros((f.shape[0], k, k))
    a[:, iu[0], iu[1]] = f[:, :iu[0].size]
    a[:, iu[1], iu[0]] = f[:, :iu[0].size]
    return a


def _solve_normal(f: np.ndarray, k: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares coefficients (n, k) from (filtered) normal-equation accumulators, and
    whether each system was well posed."""
    a = _normal_matrix(f, k)
    m = k * (k + 1) // 2
    det = np.linalg.det(a)
    ok = np.isfinite(det) & (np.abs(det) > 1e-12 * np.abs(a[:, 0, 0]) ** k)
    a[~ok] = np.eye(k)
    rhs = np.where(ok[:, np.newaxis], f[:, m:m + k], 0.0)
    return np.linalg.solve(a, rhs[..., np.newaxis])[..., 0], ok


def _se_combine(f: np.ndarray) -> np.ndarray:
    """Relative 1/rev modulation from the 3x3 normal equations (6 upper entries, 3 rhs)."""
    coef, ok = _solve_normal(f)
    out = np.hypot(coef[:, 1], coef[:, 2]) / coef[:, 0]
    return np.where(ok, out, np.nan)


def _flank_combine(f: np.ndarray) -> np.ndarray:
    """Screw gap [m] from the regression of ``x - r theta`` on [1, i_q, sign(i_q)]: the rod
    sits half a gap behind the nut on either flank, ``-(gap / 2) sign(force)``."""
    coef, ok = _solve_normal(f)
    return np.where(ok, -2.0 * coef[:, 2], np.nan)


def _tts_combine(f: np.ndarray) -> np.ndarray:
    """Largest per-phase least-squares slope of i0 on x_k (filtered means) [S]."""
    y, x, xy, xx = f[:, 0:1], f[:, 1:4], f[:, 4:7], f[:, 7:10]
    return _row_max((xy - x * y) / (xx - x * x))


def _mtel_fit(f: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Load torque ``L = a + b x`` and up-down hysteresis ``W = 2 (c + d x)`` at the local
    mean position from the regression of the motor torque on ``[1, x, s, s x]`` (``s`` the
    direction of motion, ``x`` the rod position), and where the regression is solvable."""
    coef, ok = _solve_normal(f, 4)
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


def _event_track(n_steps: int, steps: np.ndarray, vals: np.ndarray, alpha: float,
                 absolute: bool = False, min_events: int = 1) -> FeatureTrack:
    acc = np.zeros((n_steps, 2))
    valid = np.zeros(n_steps, dtype=bool)
    v = np.abs(vals) if absolute else vals
    # two events never share a step (runs last at least one step), but be safe
    np.add.at(acc[:, 0], steps, v)
    np.add.at(acc[:, 1], steps, 1.0)
    valid[steps] = True
    return _track(acc, valid, _ratio, alpha, min_events)


# --------------------------------------------------------------------------------------------
# shared preparation of one actuator: 80 Hz steps, validity windows, resistance, filter
# --------------------------------------------------------------------------------------------


def _clarke(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    alpha = (2.0 * a - b - c) / 3.0
    beta = (b - c) / np.sqrt(3.0)
    return alpha, beta


def filter_alpha(config: FeatureConfig | None = None) -> float:
    """Coefficient of the exponential filter of the 80 Hz tracks, ``1 - exp(-step / tau)``."""
    cfg = config or FeatureConfig()
    return 1.0 - np.exp(-cfg.step_s / cfg.ewma_tau_s)


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
        return _row_means(blk(a))

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
    still = _run_length_ok(np.abs(w_mean) < cfg.still_speed_rad_s,
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


def winding_resistance(steps: ActuatorSteps, still: np.ndarray, *,
                       config: FeatureConfig | None = None) -> float:
    """Phase resistance [Ohm] from the power balance ``p = R |i|^2`` of still steps carrying
    at least twice ``min_current_a``; NaN with fewer than ``min_r_estimate_blocks`` steps."""
    cfg = config or FeatureConfig()
    r_sel = still & (steps.current > 2 * cfg.min_current_a)
    if np.count_nonzero(r_sel) >= cfg.min_r_estimate_blocks:
        return float(steps.power[r_sel].sum() / steps.current_sq[r_sel].sum())
    return float("nan")


def _resistance_or_nominal(r_hat: float, mc: MotorConstants) -> float:
    return r_hat if np.isfinite(r_hat) and r_hat > 0 else mc.resistance_ohm


def winding_temperature(r_hat: float, motor: MotorConstants | None = None) -> float:
    """Winding temperature [degC] from the copper's resistance law; NaN without an estimate
    (a non-positive estimate reads as the nominal resistance)."""
    mc = motor or MotorConstants()
    if not np.isfinite(r_hat):
        return float("nan")
    r_use = _resistance_or_nominal(r_hat, mc)
    return float(mc.ref_temp_c + (r_use / mc.resistance_ohm - 1.0) / mc.copper_alpha_per_k)


# --------------------------------------------------------------------------------------------
# one function per feature (80 Hz arrays in, FeatureTrack out)
# --------------------------------------------------------------------------------------------


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
    v_cm_b = -0.5 * (_row_max(u_b) + _row_min(u_b))
    x_tts = v_cm_b[:, np.newaxis] + 0.5 * u_b  # (n, 3) [V]
    i0_b = common_current
    acc = np.column_stack([i0_b, x_tts, x_tts * i0_b[:, np.newaxis], x_tts * x_tts])
    return _track(acc, valid, _tts_combine, filter_alpha(cfg), cfg.min_valid_steps)


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
    return _track(np.column_stack([emf * omega_e, omega_e * omega_e]), valid,
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
    acc = _normal_accumulators(xs, emf)
    return _track(acc, valid, _se_combine, filter_alpha(cfg), cfg.min_valid_steps)


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
    return _track(phase_voltage_ms, valid, _bdo_combine, filter_alpha(cfg),
                  cfg.min_valid_steps)


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
    track = _track(
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
    return _normal_accumulators(np.column_stack([np.ones(n), x_rel_mm, s_dir,
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
    acc = _normal_accumulators(np.column_stack([np.ones(n), i_q, side]), x_rod - nut_position)
    track = _track(acc, flank, _flank_combine, filter_alpha(cfg), cfg.min_valid_steps)
    if min(np.count_nonzero(flank & (side > 0)),
           np.count_nonzero(flank & (side < 0))) < cfg.min_flank_steps:
        track.value = float("nan")  # one flank only: the gap was not crossed
    return track


# --------------------------------------------------------------------------------------------
# per actuator, per flight
# --------------------------------------------------------------------------------------------


def actuator_features(
    sig: Mapping[str, np.ndarray],
    *,
    aero_gradient_n_per_m: float,
    aero_bias_n: float = 0.0,
    t_amb_c: np.ndarray | None = None,
    config: FeatureConfig | None = None,
    motor: MotorConstants | None = None,
) -> tuple[dict[str, FeatureTrack], dict[str, float]]:
    """The six features of one actuator over one flight.

    Parameters
    ----------
    sig : mapping with ``ia ib ic va vb vc theta x`` (n,) at 800 Hz, SI units.
    aero_gradient_n_per_m, aero_bias_n : design aero model of the rod load at cruise,
        ``F = -(aero_gradient_n_per_m * x + aero_bias_n)`` [N].
    t_amb_c : optional ambient temperature (n,) [degC]; when given, ``F_MTEL`` uses only
        moves at cruise (constant dynamic pressure: the hinge load is linear in deflection).

    Returns
    -------
    tracks : ``ACTUATOR_FEATURES`` -> :class:`FeatureTrack` (80 Hz).
    extras : per-flight helper quantities (``psi_hat_wb``, ``r_hat_ohm``, ``load_rms_n``,
        ``speed_rms_rad_s``, ``temp_winding_est_c``, ``mtel_drag_weight_per_nm``).
    """
    cfg = config or FeatureConfig()
    steps = actuator_steps(sig, config=cfg, motor=motor)
    tracks, r_hat, psi_hat, weight = _driving_features(steps, t_amb_c, cfg,
                                                       motor or MotorConstants())
    extras = {"psi_hat_wb": psi_hat, "r_hat_ohm": r_hat,
              **_step_conditions(steps, aero_gradient_n_per_m, aero_bias_n, r_hat, motor),
              "mtel_drag_weight_per_nm": weight}
    return tracks, extras


def _driving_features(steps: ActuatorSteps, t_amb_c: np.ndarray | None, cfg: FeatureConfig,
                      mc: MotorConstants
                      ) -> tuple[dict[str, FeatureTrack], float, float, float]:
    """The six features of a drive whose inverter switches, from its 80 Hz steps; with the
    winding resistance, the flux and ``F_MTEL``'s drag weight (:func:`drag_weight`) they
    estimated."""
    windows = validity_windows(steps, config=cfg, t_amb_c=t_amb_c)
    r_hat = winding_resistance(steps, windows.still, config=cfg)
    omega_e = mc.pole_pairs * steps.speed
    emf = steps.v_q - _resistance_or_nominal(r_hat, mc) * steps.i_q  # V, q-axis back-EMF
    rotating = windows.current_ok & windows.moving

    tracks: dict[str, FeatureTrack] = {}
    tracks["F_TTS"] = leakage_conductance(steps.phase_voltage, steps.common_current,
                                          windows.electrical_ok, config=cfg)
    tracks["F_DMD"] = flux_deficit(emf, omega_e, rotating, config=cfg, motor=mc)
    psi_hat = estimated_flux(tracks["F_DMD"].value, mc)
    tracks["F_SE"] = flux_modulation(emf, omega_e, steps.cos_theta, steps.sin_theta, rotating,
                                     config=cfg)
    tracks["F_BDO"] = voltage_imbalance(steps.phase_voltage_ms,
                                        rotating & (steps.voltage > cfg.min_voltage_v),
                                        config=cfg)
    torque = 1.5 * mc.pole_pairs * psi_hat * steps.i_q  # N m, motor torque
    tracks["F_MTEL"] = friction_ratio(torque, steps.x, steps.speed, windows.steady_cruise,
                                      config=cfg)
    weight = drag_weight(torque, steps.x, steps.speed, windows.steady_cruise, config=cfg)
    tracks["F_MTWEAR"] = screw_gap(steps.x, mc.screw_radius_m * steps.theta, steps.i_q,
                                   config=cfg)
    return tracks, r_hat, float(psi_hat), weight


def _step_conditions(steps: ActuatorSteps, aero_gradient_n_per_m: float, aero_bias_n: float,
                     r_hat: float, motor: MotorConstants | None) -> dict[str, float]:
    """An actuator's operating conditions over the flight: design aero load and shaft speed
    (RMS), winding temperature from the resistance estimate (NaN without one)."""
    load_exp = -(aero_gradient_n_per_m * steps.x + aero_bias_n)  # N, design aero load
    return {"temp_winding_est_c": winding_temperature(r_hat, motor),
            "load_rms_n": float(np.sqrt(np.mean(load_exp ** 2))),
            "speed_rms_rad_s": float(np.sqrt(np.mean(steps.speed ** 2)))}


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
    return _event_track(n, steps, vals, filter_alpha(cfg), absolute=cfg.rewear_absolute,
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
        return _event_track(n, np.zeros(0, dtype=np.int64), np.zeros(0), filter_alpha(cfg))
    vel_a = np.gradient(pos_a[:n], cfg.step_s)
    vel_s = np.gradient(pos_s[:n], cfg.step_s)
    steps, vals = _stroke_end_lost_motion(xa[:n] - xs[:n], vel_a, vel_s, np.sign(iq_active[:n]),
                                          cfg)
    return _event_track(n, steps, vals, filter_alpha(cfg), absolute=True,
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


def standby_drive(active_channels: Collection[str] | None) -> str | None:
    """The winglet drive standing by on a flight whose log names its active drives (None when
    both drive: an active-active pair, or a log that names none).

    Raises ``ValueError`` when the list leaves both winglet drives idle."""
    if active_channels is None:
        return None
    idle = [p for p in WINGLET_PAIR if p not in active_channels]
    if len(idle) == 2:
        raise ValueError("active_channels names no winglet drive: the tab has no active drive")
    return idle[0] if idle else None


_NO_VALUE = FeatureSummary(float("nan"), float("nan"), 0)


def flight_features(
    channels: Mapping[str, np.ndarray],
    *,
    config: FeatureConfig | None = None,
    motor: MotorConstants | None = None,
    ground_temp_c: float | None = None,
    active_channels: Collection[str] | None = None,
    keep_tracks: bool = False,
) -> FlightFeatures:
    """The 20 features of one flight from flight-log v1 channels (``"WL1.ia"``, ...).

    ``active_channels`` (the log's optional metadata) names the drives that drove; a winglet
    drive not named stood by. A standby's inverter does not switch and its loops are idle, so
    its six motor features are not read (NaN, ``n_valid`` 0): the leakage, imbalance and
    friction tests need a switching inverter and a driving torque, and its flux estimate from
    the damping currents rests on a hundred-odd valid steps and sits 0.01-0.02 from the same
    drive's active value (docs/FEATURES.md). Its rod-end play is read instead
    (:func:`standby_play_feature`), and the active drive's ``F_REWEAR`` is NaN: a one-sided
    hinge load keeps its rod end on one flank. Without a standby (``None``, or every drive
    named) both winglet drives carry the pair's lost motion (:func:`rewear_feature`).

    ``ground_temp_c`` overrides the ground temperature when the log has no ``T_amb``.
    """
    cfg = config or FeatureConfig()
    mc = motor or MotorConstants()
    standby = standby_drive(active_channels)
    flight_cond = operating_conditions(channels)
    if ground_temp_c is not None and not np.isfinite(flight_cond["temp_ground_c"]):
        flight_cond = {"temp_ground_c": float(ground_temp_c),
                       "temp_mean_c": float(ground_temp_c)}
    tracks: dict[str, FeatureTrack] = {}
    conditions: dict[str, dict[str, float]] = {}
    steps: dict[str, ActuatorSteps] = {}
    for p in POSITIONS:
        steps[p] = actuator_steps({s: channels[f"{p}.{s}"] for s in SIGNALS}, config=cfg,
                                  motor=mc)
        r_hat = weight = float("nan")
        if p != standby:
            own, r_hat, _, weight = _driving_features(steps[p], channels.get("T_amb"), cfg, mc)
            tracks.update({f"{p}.{f}": tr for f, tr in own.items()})
        conditions[p] = {**flight_cond, **_step_conditions(
            steps[p], float(cfg.aero_gradient_n_per_m[p]), float(cfg.aero_bias_n[p]), r_hat, mc),
            "mtel_drag_weight_per_nm": weight}
    tracks.update(_rod_end_tracks(channels, steps, standby, cfg, mc))
    summaries = {n: tracks[n].summary() if n in tracks else _NO_VALUE for n in AIRCRAFT_FEATURES}
    quality = flight_quality(channels, screw_radius_m=mc.screw_radius_m,
                             pole_pairs=mc.pole_pairs,
                             electrical_offset_rad=cfg.electrical_offset_rad)
    return FlightFeatures(summaries, conditions, tracks if keep_tracks else None, quality)


def _rod_end_tracks(channels: Mapping[str, np.ndarray], steps: Mapping[str, ActuatorSteps],
                    standby: str | None, cfg: FeatureConfig, mc: MotorConstants
                    ) -> dict[str, FeatureTrack]:
    """``F_REWEAR`` of the winglet drives: the standby's play, or the pair's lost motion for
    both when neither stands by."""
    a, b = WINGLET_PAIR
    if standby is None:
        pair = rewear_feature(channels[f"{a}.x"], channels[f"{b}.x"], channels[f"{a}.theta"],
                              channels[f"{b}.theta"], config=cfg, motor=mc)
        return {f"{a}.{REWEAR_FEATURE}": pair, f"{b}.{REWEAR_FEATURE}": pair}
    active = b if standby == a else a
    play = standby_play_feature(channels[f"{active}.x"], channels[f"{standby}.x"],
                                channels[f"{active}.theta"], channels[f"{standby}.theta"],
                                steps[active].i_q, config=cfg, motor=mc)
    return {f"{standby}.{REWEAR_FEATURE}": play}
