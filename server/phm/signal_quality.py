"""Signal quality of every sensor of a flight, from the flight log alone.

Time base: 800 Hz samples in, one set of figures per channel and flight out, keyed
``"<position>.<channel>"``.

Every recorded channel (:data:`server.vocabulary.SIGNALS`) gets:

``lsb``        quantisation step [channel unit]: the smallest change between neighbouring samples.
``stuck``      share of the samples in runs of one repeated value longer than ``stuck_min_s``
               [-]: a frozen channel; a live noisy one repeats a value a few samples at most.
``saturated``  share of the samples at the flight's extreme values in runs of more than one
               sample [-]: a channel clipped on a rail sits at it; a live one touches its
               extreme once.
The resolver and LVDT channels also get

``noise``      noise floor [channel unit, rms]: on *still* samples (the drive holding, motor
               speed below ``still_speed_rad_s`` for at least ``still_min_s``, read from the
               resolver) the second difference of a channel is its white noise (variance 6
               sigma^2 for white noise) plus a curvature that a hold does not have at 800 Hz.
               The rms of the second difference, winsorised at ``winsor_k`` robust scales
               against spikes, over sqrt(6).

A phase channel's own floor would also hold the loops' reaction to the noise they are fed and
any ripple of the drive itself (an open inverter leg multiplies it fifty-fold), so it is not
computed. The current and voltage sensors' noise is read where the physics cancels the drive:
the three phase currents of a star winding sum to zero, and the three pole voltages' common
mode is smooth on a hold, so

``i_sum``      ``noise`` of ``ia + ib + ic`` over sqrt(3) [A]: the current sensors' noise alone
               (a winding-to-frame leakage adds a little);
``v_sum``      ``noise`` of ``va + vb + vc`` over sqrt(3) [V]: the voltage sensors' noise.

The LVDT also gets

``offset``     [m]: the rod position read against the motor shaft, ``x - r theta``, on still
               samples, midway between its medians with the motor torque one way and the
               other (sign of ``i_q``): the screw's backlash puts the nut on either flank, and
               the midpoint does not move with it. Rigging and deflection give every drive its
               own value; a drifting LVDT moves it.

NaN where the flight has too few still samples (``min_still``, or ``min_flank`` per flank
for the offset). One compiled pass per channel The figures are compared with their
healthy bands by :mod:`server.phm.sensor_health`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from server.vocabulary import POSITIONS, SIGNALS

from .signal_quality_loops import (
    channel_counts,
    clipped_mean_square,
    hold_flanks,
    second_differences,
    sparse_abs_median,
)

__all__ = ["FLOOR_CHANNELS", "QualityConfig", "channel_quality", "flight_quality",
           "still_samples"]

#: the channels whose noise floor is the sensor's own, and their sensor
FLOOR_CHANNELS: dict[str, str] = {"i_sum": "current", "v_sum": "voltage", "theta": "resolver",
                                  "x": "lvdt"}


@dataclass(frozen=True)
class QualityConfig:
    """Windows of the signal-quality figures (SI).

    The still rule is the feature extraction's (``server.phm.features.FeatureConfig``:
    0.5 rad/s for 0.3 s on 80 Hz block means), so that a hold means the same for both.
    """

    #: Hz, rate of the flight-log channels (format v1)
    sample_rate_hz: float = 800.0
    #: samples per block of the still rule (80 Hz blocks)
    decimation: int = 10
    #: rad/s, |block-mean motor speed| below which the drive holds
    still_speed_rad_s: float = 0.5
    #: s, least length of a hold
    still_min_s: float = 0.3
    #: robust scales at which second differences are winsorised: a spike or a hold's edge
    #: then weighs as a 4-sigma sample, not as its full size
    winsor_k: float = 4.0
    #: s, a run of one repeated value longer than this is a stuck span (0.1 s = 80 samples:
    #: a live channel with noise of one LSB repeats a value for a few samples)
    stuck_min_s: float = 0.1
    #: least still samples for a noise floor (1 s of holds)
    min_still: int = 800
    #: least still samples on each flank for an LVDT offset (0.1 s)
    min_flank: int = 80
    #: A, |i_q| that puts the screw's nut on a flank: below it a worn screw's nut may sit
    #: anywhere in its gap (the feature code's least current)
    min_flank_current_a: float = 0.3


def _run_lengths(mask: np.ndarray) -> np.ndarray:
    """Length of the run of True each True sample of ``mask`` belongs to (0 where False)."""
    edges = np.diff(np.r_[False, mask, False].astype(np.int8))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    if starts.size == 0:
        return np.zeros(mask.size, dtype=np.int64)
    run_id = np.maximum(np.cumsum(edges[:-1] == 1) - 1, 0)
    return np.where(mask, (ends - starts)[run_id], 0)


def still_samples(theta: np.ndarray, config: QualityConfig | None = None) -> np.ndarray:
    """800 Hz mask of the samples inside holds, from the resolver angle ``theta`` [rad]."""
    cfg = config or QualityConfig()
    d = cfg.decimation
    n = theta.size // d
    if n < 2:
        return np.zeros(theta.size, dtype=bool)
    blocks = np.asarray(theta[: n * d], dtype=np.float64).reshape(n, d).mean(axis=1)
    speed = np.abs(np.gradient(blocks, d / cfg.sample_rate_hz))
    min_blocks = max(1, int(round(cfg.still_min_s * cfg.sample_rate_hz / d)))
    still = _run_lengths(speed < cfg.still_speed_rad_s) >= min_blocks
    return np.r_[np.repeat(still, d), np.zeros(theta.size - n * d, dtype=bool)]


def _noise_floor(v: np.ndarray, still: np.ndarray, cfg: QualityConfig,
                 v2: np.ndarray | None = None, v3: np.ndarray | None = None) -> float:
    """The noise floor of ``v`` (of ``v + v2 + v3`` when both are given) on ``still``
    samples."""
    d2 = second_differences(v, v2, v3, still)
    if d2.size < cfg.min_still:
        return float("nan")
    # a second difference has zero mean on a hold; its robust scale from a quarter of the
    # samples is as good for a winsorising limit and four times cheaper
    scale = 1.4826 * float(sparse_abs_median(d2, 4))
    if scale <= 0.0:  # quantised below one step: winsorise at the spread of the values
        scale = float(np.std(d2))
    return float(np.sqrt(clipped_mean_square(d2, cfg.winsor_k * scale) / 6.0))


def channel_quality(v: np.ndarray, still: np.ndarray | None = None,
                    config: QualityConfig | None = None) -> dict[str, float]:
    """``lsb``, ``stuck`` and ``saturated`` of one channel, and its ``noise`` floor when
    ``still`` (its 800 Hz hold mask, the same length) is given."""
    cfg = config or QualityConfig()
    v = np.asarray(v, dtype=np.float64)
    if v.size < 2:
        return {"lsb": float("nan"), "stuck": 0.0, "saturated": 0.0}
    # a run of n equal samples is a run of n - 1 zero steps
    lsb, stuck, saturated = channel_counts(v, float(v.max()), float(v.min()),
                                           int(round(cfg.stuck_min_s * cfg.sample_rate_hz)))
    out = {"lsb": float(lsb), "stuck": stuck / v.size, "saturated": saturated / v.size}
    if still is not None:
        out["noise"] = _noise_floor(v, still, cfg)
    return out


def _lvdt_offset(sig: Mapping[str, np.ndarray], still: np.ndarray, radius_m: float,
                 pole_pairs: int, electrical_offset_rad: float, cfg: QualityConfig) -> float:
    # only holds count: i_q and x - r theta there alone
    up, down = hold_flanks(sig["ia"], sig["ib"], sig["ic"], sig["theta"], sig["x"], still,
                           radius_m, pole_pairs, electrical_offset_rad, cfg.min_flank_current_a)
    if min(up.size, down.size) < cfg.min_flank:
        return float("nan")
    return 0.5 * float(np.median(up) + np.median(down))


def flight_quality(channels: Mapping[str, np.ndarray], *, screw_radius_m: float,
                   pole_pairs: int, electrical_offset_rad: float = 0.0,
                   config: QualityConfig | None = None) -> dict[str, dict[str, float]]:
    """The signal-quality figures of every actuator of a flight (flight-log v1 channels in,
    ``"<position>.<channel>" -> {metric: value}`` out); ``screw_radius_m`` is the rod travel
    per radian of motor shaft [m/rad], ``pole_pairs`` and ``electrical_offset_rad`` the
    motor's electrical angle from the resolver."""
    cfg = config or QualityConfig()
    out: dict[str, dict[str, float]] = {}
    for p in POSITIONS:
        sig = {s: np.asarray(channels[f"{p}.{s}"], dtype=np.float64) for s in SIGNALS}
        n = min(a.size for a in sig.values())
        sig = {s: a[:n] for s, a in sig.items()}
        still = still_samples(sig["theta"], cfg)
        for s, v in sig.items():
            # a phase channel's own floor carries the drive: its sensor is read on the sum
            out[f"{p}.{s}"] = channel_quality(v, still if s in FLOOR_CHANNELS else None, cfg)
        root3 = math.sqrt(3.0)
        out[f"{p}.i_sum"] = {"noise": _noise_floor(sig["ia"], still, cfg, sig["ib"],
                                                   sig["ic"]) / root3}
        out[f"{p}.v_sum"] = {"noise": _noise_floor(sig["va"], still, cfg, sig["vb"],
                                                   sig["vc"]) / root3}
        out[f"{p}.x"]["offset"] = _lvdt_offset(sig, still, screw_radius_m, pole_pairs,
                                               electrical_offset_rad, cfg)
    return out
