"""Operating scenario: the reference cycle per surface and its per-flight warp (paper eq. (1)).

The reference cycle lasts ``REFERENCE_DURATION_S`` (120 s of actuator activity) and is made of
piecewise-linear position waypoints per surface [mm, rod coordinates], a dynamic-pressure profile
``q`` (0 on ground, 1 at cruise) and an altitude fraction for the ambient temperature (0 on
ground, 1 at cruise where the air is at -40 degC). Phases: ground check sweeps (0-24 s), take-off
and climb (24-44 s), cruise holds under load with small corrections and reversals (44-92 s),
approach (92-110 s), landing (110-120 s). Every flight contains slow moves (a few mm/s, lasting
seconds), holds under aerodynamic load lasting seconds and direction reversals under load.

Warp per flight (eq. (1)): the time axis is stretched by ``sigma_t ~ N(1, 0.1)`` (common to the
flight), and per surface ``x = sigma_x x_ref + sigma_x0`` with ``sigma_x ~ N(1, 0.3)``,
``sigma_x0 ~ N(0, 0.1 * stroke)`` (stroke 60 mm), and ``F = sigma_F F_set + sigma_F0`` with
``sigma_F ~ N(1, 0.3)``, ``sigma_F0 ~ N(0, 0.1 * nominal load)``. The load set-point is the
aerodynamic hinge load of the (warped) command, ``F_set = -q (K_a x + F_bias)`` per actuator, plus
a small band-limited gust. Commands are clipped to +-27 mm (inside the +-30 mm stroke).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.signal import lfilter

from server.vocabulary import POSITIONS

from .fleet import SURFACE_OF, WINGLET, WINGTIP
from .params import OUT_HZ

__all__ = [
    "REFERENCE_DURATION_S",
    "CRUISE_TEMP_C",
    "COMMAND_LIMIT_M",
    "Warp",
    "Scenario",
    "draw_warp",
    "build_scenario",
    "reference_waypoints",
]

REFERENCE_DURATION_S = 120.0
CRUISE_TEMP_C = -40.0
COMMAND_LIMIT_M = 0.027
STROKE_M = 0.060

# (t [s], x [mm]) waypoints of the winglet tab and of the wingtip
_WL = np.array([
    # ground check: slow full sweeps, fast sweeps, small slow reversals
    (0, 0), (1, 0), (4, 20), (6, 20), (11, -20), (13, -20), (16, 0), (17, 0),
    (17.4, 12), (18.2, -12), (18.6, 0), (20, 0), (21.5, 5), (23, -5), (24, 0),
    # take-off and climb: slow moves to growing deflections, holds
    (26, 8), (30, 8), (32, 12), (35, 12), (37, 6), (40, 6), (42, 10), (44, 10),
    # cruise: holds under load, small slow corrections, reversals under load
    (50, 10), (51, 12), (56, 12), (57, 10.5), (58, 12), (59, 10.5), (60, 11), (66, 11),
    (68, 15), (74, 15), (75, 13.5), (76, 15), (77, 13.5), (78, 14), (83, 14), (86, 5), (92, 5),
    # approach
    (95, -10), (99, -10), (101, -14), (104, -14), (106, -8), (110, -8),
    # landing
    (113, 0), (115, 0), (116.5, -6), (118, 0), (120, 0),
], dtype=float)
_WT = np.array([
    (0, 0), (2, 0), (5, -15), (7, -15), (12, 15), (14, 15), (16, 0), (17, 0),
    (17.3, -10), (17.9, 10), (18.2, 0), (20, 0), (21.5, -4), (23, 4), (24, 0),
    (27, 6), (31, 6), (33, 9), (36, 9), (38, 4), (41, 4), (43, 7), (44, 7),
    (49, 7), (50, 9), (55, 9), (56, 7.5), (57, 9), (58, 7.5), (59, 8), (65, 8),
    (67, 12), (73, 12), (74, 10.5), (75, 12), (76, 10.5), (77, 11), (82, 11), (85, 3), (92, 3),
    (96, -8), (100, -8), (102, -12), (105, -12), (107, -5), (110, -5),
    (113, 0), (115, 0), (116.5, 5), (118, 0), (120, 0),
], dtype=float)
_Q = np.array([(0, 0), (24, 0), (26, 0.3), (44, 0.8), (46, 1.0), (90, 1.0), (93, 0.7),
               (108, 0.6), (111, 0.4), (117, 0.05), (120, 0.0)], dtype=float)
_ALT = np.array([(0, 0), (24, 0), (44, 0.95), (46, 1.0), (90, 1.0), (110, 0.15), (114, 0),
                 (120, 0)], dtype=float)
_SURFACES = (WINGLET, WINGTIP)


def reference_waypoints() -> dict[str, np.ndarray]:
    """The reference cycle tables (copies): ``WL``/``WT`` [s, mm], ``q`` and ``alt`` [s, -]."""
    return {"WL": _WL.copy(), "WT": _WT.copy(), "q": _Q.copy(), "alt": _ALT.copy()}


@dataclass(frozen=True)
class Warp:
    """Per-flight warp factors of eq. (1); per-surface tuples are (winglet, wingtip)."""

    sigma_t: float
    sigma_x: tuple[float, float]
    sigma_x0_m: tuple[float, float]
    sigma_f: tuple[float, float]
    sigma_f0_n: tuple[float, float]


@dataclass(frozen=True)
class Scenario:
    """Inputs of one flight at 800 Hz."""

    t: np.ndarray  # s, (n,)
    x_cmd: np.ndarray  # m, (n, 3) per position WL1, WL2, WT
    f_ext: np.ndarray  # N per actuator along +x, (n, 2) per surface WL, WT
    t_amb: np.ndarray  # degC, (n,)
    q: np.ndarray  # -, dynamic pressure fraction, (n,)


def draw_warp(rng: np.random.Generator) -> Warp:
    """Draw eq. (1) factors; scales are kept positive (truncated at 3 sigma)."""
    def tn(mean: float, sd: float) -> float:
        return float(mean + sd * np.clip(rng.standard_normal(), -3.0, 3.0))

    sigma_t = max(tn(1.0, 0.1), 0.75)
    sx = (max(tn(1.0, 0.3), 0.25), max(tn(1.0, 0.3), 0.25))
    sx0 = (tn(0.0, 0.1 * STROKE_M), tn(0.0, 0.1 * STROKE_M))
    sf = (max(tn(1.0, 0.3), 0.25), max(tn(1.0, 0.3), 0.25))
    sf0 = tn(0.0, 0.1 * WINGLET.nominal_load_n), tn(0.0, 0.1 * WINGTIP.nominal_load_n)
    return Warp(sigma_t=sigma_t, sigma_x=sx, sigma_x0_m=sx0, sigma_f=sf, sigma_f0_n=sf0)


def build_scenario(warp: Warp, ground_temp_c: float, rng: np.random.Generator, *,
                   duration_s: float = REFERENCE_DURATION_S,
                   cruise_temp_c: float = CRUISE_TEMP_C) -> Scenario:
    """Sample the warped cycle at 800 Hz; the recording lasts ``duration_s * sigma_t``.

    ``duration_s`` rescales the reference cycle (a shorter recording is the same cycle, faster).
    ``rng`` draws the gust sequence. ``cruise_temp_c``: the air at cruise (a test-station
    ambient offset shifts it with the ground's).
    """
    if duration_s <= 0:
        raise ValueError("duration_s must be positive")
    total = duration_s * warp.sigma_t
    n = int(round(total * OUT_HZ))
    t = np.arange(n) / OUT_HZ
    tau = t * (REFERENCE_DURATION_S / total)  # reference time of each sample
    q = np.interp(tau, _Q[:, 0], _Q[:, 1])
    alt = np.interp(tau, _ALT[:, 0], _ALT[:, 1])
    t_amb = ground_temp_c + (cruise_temp_c - ground_temp_c) * alt
    x_surf = []
    f_surf = []
    # gust: first-order low-pass (2 Hz) white noise, 3 % of the nominal load, scaled by q
    a = np.exp(-2.0 * np.pi * 2.0 / OUT_HZ)
    for i, (table, surf) in enumerate(((_WL, _SURFACES[0]), (_WT, _SURFACES[1]))):
        x_ref = np.interp(tau, table[:, 0], table[:, 1]) * 1e-3
        x = np.clip(warp.sigma_x[i] * x_ref + warp.sigma_x0_m[i], -COMMAND_LIMIT_M,
                    COMMAND_LIMIT_M)
        f_set = -q * (surf.aero_stiffness_n_per_m * x + surf.aero_bias_n)
        white = rng.standard_normal(n) * np.sqrt(1.0 - a * a)
        gust = lfilter([1.0], [1.0, -a], white) * 0.03 * surf.nominal_load_n * q
        f = warp.sigma_f[i] * f_set + warp.sigma_f0_n[i] + gust
        x_surf.append(x)
        f_surf.append(f)
    x_cmd = np.stack([x_surf[SURFACE_OF[p]] for p in POSITIONS], axis=1)
    f_ext = np.stack(f_surf, axis=1)
    return Scenario(t=t, x_cmd=np.ascontiguousarray(x_cmd), f_ext=np.ascontiguousarray(f_ext),
                    t_amb=t_amb, q=q)
