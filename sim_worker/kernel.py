"""The real-time half-wing model: one flat numba kernel over float64 arrays.

Fixed step ``dt = 1 / 12 kHz``; current PI every step, speed PI every 3 steps (4 kHz), position P
every 12 steps (1 kHz); sensor outputs every 15 steps (800 Hz). Per EMA the states are the d-q
currents (peak, amplitude invariant, magnetising equivalent), rotor angle and speed, winding
temperature and the controller states; per surface the deflection and its rate.

Subsystems, each a small function below, wired once in :func:`simulate`:

* inverter: averaged legs, pole voltage ``d_k U_dc`` minus the conduction drop; min-max zero
  sequence (space-vector equivalent); a MOSFET whose base drive is open never turns on while its
  diode still conducts, so the leg's effective duty follows the sign of the leg current (upper
  switch open: ``d_eff = d`` while ``i_k < 0``, else 0; lower open: 1 while ``i_k < 0``, else
  ``d``);
* PMSM in d-q with R(T), psi(T), magnet loss ``(1 - h)``, static eccentricity as a flux modulation
  by the mechanical angle; turn-to-turn short as a shorted loop on phase a (quasi-static) whose
  reflected current and a winding-to-frame leakage enter the terminal currents;
* ball screw: load-dependent friction from the direct/back-driving efficiencies, Karnopp stick;
* link: screw and rod-end compliance and backlash folded into one dead-zone spring with damping;
  the LVDT rod position is recovered from the force through the screw part;
* surface: one rigid body per surface with aerodynamic force input and hinge damping;
* thermal: single body, copper + short-circuit losses, to ambient through R_th;
* sensors: offset, noise (in-kernel xorshift generator seeded from a numpy Generator),
  quantisation; a failed sensor's clamp (stuck, clipped: test-station injections) on the
  reading the controller uses;
* control: current PI every step, speed PI every 3 steps, position P every 12 steps;
* active-standby: a channel flagged standby (``P.STANDBY``) does not drive. Its inverter's gates
  are off and a normally-closed contactor closes its windings on a star of damping resistors
  ``R_d``, so the pole voltage is ``-R_d i_k`` (the averaged legs with duty 0 and ``R_d`` in
  place of the conduction resistance); the back-driven magnet motor gives the damping torque
  its back-EMF drives. Its loops do not run, its LVDT is not in the surface's consolidated
  feedback, an open MOSFET of its (gated-off) inverter changes nothing, and its winding is not
  referred to the DC link, so a turn-to-turn short leaks no current to the frame. Its
  sensors and its link, screw and rod end are those of an active channel.

The helpers are compiled with ``inline="always"``: numba inlines them into :func:`simulate` before
type inference, so the kernel stays one loop with the same floating-point operations, in the same
order, as a single hand-written function.

The two compiled functions, :func:`simulate` and :func:`_position_loop`, are compiled with
``fastmath={"contract", "arcp"}``, which also governs the inlined helpers (their code is compiled
as the caller's: their own flags make no difference to the outputs): a multiply and an add may
fuse into one FMA, and a division may become a multiplication by the reciprocal. Those two keep
IEEE semantics for NaN and infinities (no ``nnan``/``ninf``) and never reorder a sum (no
``reassoc``), and take about a quarter off the kernel's time. The outputs are deterministic for
one machine and CPU build; the last bits differ from a strict-IEEE build's and, through FMA,
from a CPU without fused multiply-add.
"""

from __future__ import annotations

import math
from enum import IntEnum

import numpy as np
from numba import njit

from .params import OUT_HZ, POS_DIV, SPEED_DIV, STEP_HZ, P, S

__all__ = ["simulate", "simulate_motor", "warm_up", "A", "N_ACC", "D", "N_DBG", "N_SIG"]

SQRT3_2 = math.sqrt(3.0) / 2.0
# FMA contraction and reciprocals only: see the module docstring
_FASTMATH = {"contract", "arcp"}
N_SIG = 8  # ia ib ic va vb vc theta x
#: A: a motor current below this is none (the current sensors' LSB is 10 orders of magnitude
#: larger); see _no_subnormal
_I_NONE = 1e-30


class A(IntEnum):
    """Indices of the per-EMA accumulators (flight summary and energy audit)."""

    TW_SUM = 0  # degC * samples
    TW_MAX = 1  # degC
    F2_SUM = 2  # N^2 * samples, link force squared
    WORK_SCREW = 3  # N m, integral of |F| |v_nut| dt (Archard sliding work, screw)
    TRAVEL = 4  # m, integral of |v_nut| dt
    I2_SUM = 5  # A^2 * samples, i_d^2 + i_q^2
    N = 6  # samples
    E_IN = 7  # J, electrical energy into the motor terminals
    E_CU = 8  # J, copper losses
    E_FRIC = 9  # J, screw friction
    E_LINK = 10  # J, work delivered to the link (rod)
    WORK_ROD = 11  # N m, integral of |F| |v_attachment| dt (rod-end sliding work)
    E_FAULT = 12  # J, losses in the shorted turns and leakage
    STILL_S = 13  # s, time with the motor stuck (Karnopp)


N_ACC = 14


class D(IntEnum):
    """Indices of the per-EMA true-state debug outputs at 800 Hz (ground truth, not a sensor)."""

    ID = 0
    IQ = 1
    W = 2  # rad/s motor
    TW = 3  # degC
    F = 4  # N link force
    XROD = 5  # m true rod position
    TE = 6  # N m
    IQREF = 7  # A


N_DBG = 8

# per-EMA state layout
_ID, _IQ, _TH, _W, _TW, _IW, _WREF, _IQREF, _ICD, _ICQ = range(10)
_DA, _DB, _DC, _WF, _THPREV, _BDOPOS, _IA, _IB, _IC, _UA = range(10, 20)
_UB, _UC, _VCM, _PLOSS, _XM, _XROD, _WPREV, _COS, _SIN, _THE = range(20, 30)
_NST = 30
# per-EMA coefficients held for one output period (temperature dependent)
_C_R, _C_RON, _C_PSI, _C_AD, _C_AQ = range(5)
# and, in the same rows, per-EMA limits the step would otherwise recompute (with a division or a
# square) every step
_C_UMAX, _C_DT_J, _C_UMAX2 = range(5, 8)
_NCOEF = 8


@njit(cache=True, inline="always")
def _bits53(rng: np.ndarray, k: int) -> np.uint64:
    """Next draw of EMA ``k``'s xorshift generator, as an integer below 2^53 (a uniform in [0, 1)
    is that times 2^-53)."""
    x = rng[k]
    x ^= x << np.uint64(13)
    x ^= x >> np.uint64(7)
    x ^= x << np.uint64(17)
    rng[k] = x
    return x >> np.uint64(11)


@njit(cache=True, inline="always")
def _noise(rng: np.ndarray, k: int) -> float:
    """Zero-mean unit-variance noise (triangular, sum of two uniforms).

    The two uniforms are added as integers and converted once: both are multiples of 2^-53, so
    the float sum of the two uniforms rounds exactly as the conversion of the integer sum."""
    b = _bits53(rng, k)
    b += _bits53(rng, k)
    return (float(b) * (1.0 / 9007199254740992.0) - 1.0) * 2.449489742783178


@njit(cache=True, inline="always")
def _quant(v: float, lsb: float) -> float:
    """``v`` rounded to the nearest multiple of ``lsb``. np.floor keeps the value a float
    (math.floor returns an int in numba: two extra conversions on the critical path; the same
    value for any finite ``v``)."""
    return np.floor(v / lsb + 0.5) * lsb


# ---- sensors -------------------------------------------------------------------------------


@njit(cache=True, inline="always")
def _measure(v: float, noise_rms: float, lsb: float, rng: np.ndarray, k: int) -> float:
    """One sensor reading: ``v`` (offset already added) plus noise from EMA ``k``'s generator,
    quantised to the sensor's LSB."""
    return _quant(v + noise_rms * _noise(rng, k), lsb)


@njit(cache=True, inline="always")
def _clamp(v: float, on: float, lo: float, hi: float) -> float:
    """A failed sensor's reading: held in [lo, hi] when its clamp is on (stuck: lo == hi;
    clipped: +-level), after noise and quantisation, where a saturated or frozen converter
    output sits; the controller reads it as it is."""
    return min(max(v, lo), hi) if on > 0.5 else v


@njit(cache=True, inline="always")
def _sample_currents(par: np.ndarray, k: int, rng: np.ndarray, ia: float, ib: float, ic: float
                     ) -> tuple[float, float, float]:
    ni = par[k, P.N_I]
    lsb_i = par[k, P.LSB_I]
    on, lo, hi = par[k, P.CL_I], par[k, P.LO_I], par[k, P.HI_I]
    return (_clamp(_measure(ia + par[k, P.OFF_IA], ni, lsb_i, rng, k), on, lo, hi),
            _clamp(_measure(ib + par[k, P.OFF_IB], ni, lsb_i, rng, k), on, lo, hi),
            _clamp(_measure(ic + par[k, P.OFF_IC], ni, lsb_i, rng, k), on, lo, hi))


@njit(cache=True, inline="always")
def _sample_lvdt(par: np.ndarray, st: np.ndarray, k: int, rng: np.ndarray) -> float:
    return _clamp(_measure(st[k, _XROD] + par[k, P.OFF_X], par[k, P.N_X], par[k, P.LSB_X], rng,
                           k), par[k, P.CL_X], par[k, P.LO_X], par[k, P.HI_X])


@njit(cache=True, inline="always")
def _record_signals(out: np.ndarray, j: int, k: int, par: np.ndarray, rng: np.ndarray,
                    ia_m: float, ib_m: float, ic_m: float, ua: float, ub: float, uc: float,
                    th_m: float) -> None:
    """Recorded sensor channels 0-6 at an output instant (the LVDT, channel 7, is sampled
    after the speed loop)."""
    nv = par[k, P.N_V]
    lsb_v = par[k, P.LSB_V]
    on, lo, hi = par[k, P.CL_V], par[k, P.LO_V], par[k, P.HI_V]
    out[j, k, 0] = ia_m
    out[j, k, 1] = ib_m
    out[j, k, 2] = ic_m
    out[j, k, 3] = _clamp(_measure(ua, nv, lsb_v, rng, k), on, lo, hi)
    out[j, k, 4] = _clamp(_measure(ub, nv, lsb_v, rng, k), on, lo, hi)
    out[j, k, 5] = _clamp(_measure(uc, nv, lsb_v, rng, k), on, lo, hi)
    out[j, k, 6] = th_m


# ---- frames --------------------------------------------------------------------------------


@njit(cache=True, inline="always")
def _electrical_angle(the: float, the_prev: float, c_prev: float, s_prev: float, exact: bool
                      ) -> tuple[float, float]:
    """cos and sin of the electrical angle ``the``: exact when ``exact`` (once per output period,
    which bounds the drift), otherwise the previous step's pair rotated by the small increment."""
    if exact:
        return math.cos(the), math.sin(the)
    d1 = the - the_prev
    d2 = d1 * d1
    cd = 1.0 - d2 * (0.5 - d2 * (1.0 / 24.0))
    sd = d1 * (1.0 - d2 * (1.0 / 6.0 - d2 * (1.0 / 120.0)))
    return c_prev * cd - s_prev * sd, s_prev * cd + c_prev * sd


@njit(cache=True, inline="always")
def _phase_axes(c: float, sn: float) -> tuple[float, float, float, float]:
    """(cos, sin) of the phase b and phase c axes, -120 and +120 degrees from phase a."""
    return (-0.5 * c + SQRT3_2 * sn, -0.5 * sn - SQRT3_2 * c,
            -0.5 * c - SQRT3_2 * sn, -0.5 * sn + SQRT3_2 * c)


@njit(cache=True, inline="always")
def _rotate_small(c: float, sn: float, d: float) -> tuple[float, float]:
    """(cos, sin) rotated by a small angle ``d`` (first order)."""
    return c - sn * d, sn + c * d


@njit(cache=True, inline="always")
def _park(xa: float, xb: float, xc: float, c: float, sn: float, cb: float, sb: float,
          cc: float, sc: float) -> tuple[float, float]:
    """Amplitude-invariant Park transform of three phase quantities -> (d, q)."""
    return ((2.0 / 3.0) * (xa * c + xb * cb + xc * cc),
            -(2.0 / 3.0) * (xa * sn + xb * sb + xc * sc))


# ---- inverter ------------------------------------------------------------------------------


@njit(cache=True, inline="always")
def _leg_duty(d: float, i: float, upper_open: float) -> float:
    """Effective duty of a leg with one MOSFET that never turns on (its diode still conducts)."""
    if upper_open > 0.5:
        return d if i < 0.0 else 0.0
    return 1.0 if i < 0.0 else d


@njit(cache=True, inline="always")
def _current_sign_held(i_leg: float, held: float) -> float:
    """1 while the faulty leg's current flows out of the leg, 0 while into it; ``held`` (the
    last value) within +-0.05 A, so that the leg does not chatter around zero current."""
    if i_leg > 0.05:
        return 1.0
    if i_leg < -0.05:
        return 0.0
    return held


@njit(cache=True, inline="always")
def _open_leg_duties(leg: int, positive: float, upper_open: float, da: float, db: float,
                     dc: float) -> tuple[float, float, float]:
    """Duties (a, b, c) as applied with a base-drive-open MOSFET on ``leg``."""
    isign = 1.0 if positive > 0.5 else -1.0
    if leg == 0:
        da = _leg_duty(da, isign, upper_open)
    elif leg == 1:
        db = _leg_duty(db, isign, upper_open)
    else:
        dc = _leg_duty(dc, isign, upper_open)
    return da, db, dc


@njit(cache=True, inline="always")
def _phase_voltages(da: float, db: float, dc: float, udc: float, ron: float, ia: float,
                    ib: float, ic: float) -> tuple[float, float, float, float]:
    """Averaged legs: pole voltages ``d U_dc`` minus the conduction drop, referred to the motor's
    floating star point -> (u_a, u_b, u_c, common-mode voltage against the DC mid-point)."""
    va = da * udc - ron * ia
    vb = db * udc - ron * ib
    vc = dc * udc - ron * ic
    vmean = (va + vb + vc) / 3.0
    return va - vmean, vb - vmean, vc - vmean, vmean - 0.5 * udc


@njit(cache=True, inline="always")
def _svm_duties(udr: float, uqr: float, cm: float, sm: float, cbm: float, sbm: float,
                udc: float) -> tuple[float, float, float]:
    """Voltage reference -> leg duties (a, b, c): inverse Park on the measured angle, min-max
    zero sequence (space-vector equivalent), clamped to [0, 1]."""
    uar = udr * cm - uqr * sm
    ubr = udr * cbm - uqr * sbm
    ucr = -uar - ubr
    u0 = -0.5 * (max(uar, max(ubr, ucr)) + min(uar, min(ubr, ucr)))
    return (min(max(0.5 + (uar + u0) / udc, 0.0), 1.0),
            min(max(0.5 + (ubr + u0) / udc, 0.0), 1.0),
            min(max(0.5 + (ucr + u0) / udc, 0.0), 1.0))


# ---- PMSM ----------------------------------------------------------------------------------


@njit(cache=True, inline="always")
def _no_subnormal(i: float) -> float:
    """``i``, or 0 below ``_I_NONE``: a standby drive's currents decay geometrically while its
    shaft sticks (no back-EMF, windings closed on the damping star) and, rounded to nearest,
    settle on the smallest subnormal float instead of 0; x86 cores compute subnormals in
    microcode, which made a flight about four times slower on an Intel Xeon."""
    return 0.0 if abs(i) < _I_NONE else i


@njit(cache=True, inline="always")
def _pmsm_currents(id_: float, iq: float, ud: float, uq: float, we: float, r: float,
                   ld: float, lq: float, psi: float, dpsi_dt: float, ad: float, aq: float
                   ) -> tuple[float, float]:
    """PMSM d-q current step, exact for frozen speed: ``a = exp(-dt R / L)``.

    L_d di_d/dt = u_d - R i_d + w_e L_q i_q - dpsi/dt;  L_q di_q/dt = u_q - R i_q - w_e (L_d i_d
    + psi).
    """
    # coupling evaluated at the mid-step (trapezoidal predictor) keeps the rotation accurate
    id_p = ad * id_ + (1.0 - ad) * (ud + we * lq * iq - dpsi_dt) / r
    iq_p = aq * iq + (1.0 - aq) * (uq - we * (ld * id_ + psi)) / r
    id_n = ad * id_ + (1.0 - ad) * (ud + we * lq * 0.5 * (iq + iq_p) - dpsi_dt) / r
    iq_n = aq * iq + (1.0 - aq) * (uq - we * (ld * 0.5 * (id_ + id_p) + psi)) / r
    return _no_subnormal(id_n), _no_subnormal(iq_n)


@njit(cache=True, inline="always")
def _pmsm_torque(id_: float, iq: float, pp: float, ld: float, lq: float, psi: float) -> float:
    return 1.5 * pp * (psi * iq + (ld - lq) * id_ * iq)


@njit(cache=True, inline="always")
def _eccentric_flux(psi: float, eps: float, phi: float, th: float, w: float
                    ) -> tuple[float, float]:
    """PM flux linkage and its time derivative with static eccentricity: the air gap, hence the
    flux, is modulated by the mechanical angle ``th`` (narrowest gap at ``phi``)."""
    if eps == 0.0:
        return psi, 0.0
    ang = th - phi
    return psi * (1.0 + eps * math.cos(ang)), -psi * eps * math.sin(ang) * w


@njit(cache=True, inline="always")
def _turn_short(sigma: float, r_f: float, g_leak: float, ed: float, eq: float, c: float,
                sn: float, rs: float, v_frame: float) -> tuple[float, float, float]:
    """Turn-to-turn short on a fraction ``sigma`` of phase a as a quasi-static shorted loop
    (``ed``, ``eq``: induced d-q voltages), plus the winding-to-frame leakage at ``v_frame``
    -> (ampere-turns the healthy part of phase a draws, leakage current, fault losses [W])."""
    if sigma > 0.0:
        ea = ed * c - eq * sn
        i_f = sigma * ea / (r_f + sigma * rs)
        i0 = g_leak * v_frame
        return sigma * i_f, i0, i_f * i_f * (r_f + sigma * rs) + i0 * v_frame
    return 0.0, 0.0, 0.0


@njit(cache=True, inline="always")
def _terminal_currents(id_: float, iq: float, c: float, sn: float, cb: float, sb: float,
                       dlt: float, i0: float) -> tuple[float, float, float]:
    """Phase currents: magnetising currents plus the shorted loop's reflection and the leakage
    (both on phase a; the leakage returns through the frame, not through phases b and c)."""
    ia0 = id_ * c - iq * sn
    ib0 = id_ * cb - iq * sb
    return ia0 + (2.0 / 3.0) * dlt + i0, ib0 - dlt / 3.0, -ia0 - ib0 - dlt / 3.0


# ---- control -------------------------------------------------------------------------------


@njit(cache=True, inline="always")
def _lerp(a: np.ndarray, j: int, jn: int, col: int, frac: float) -> float:
    """Input channel ``col`` between output samples ``j`` and ``jn`` (linear)."""
    return a[j, col] + frac * (a[jn, col] - a[j, col])


@njit(cache=True, error_model="numpy", fastmath=_FASTMATH)
def _position_loop(par: np.ndarray, st: np.ndarray, xcmd: np.ndarray, j: int, jn: int,
                   frac: float, rng: np.ndarray, xfb: np.ndarray, nfb: np.ndarray) -> None:
    """Position P on the consolidated LVDT of each surface: the mean of its active channels'
    LVDTs (two active winglet channels exchange their measurements, which avoids force fight;
    a standby channel's LVDT is sampled but not fed back)."""
    n_ema = par.shape[0]
    xfb[:] = 0.0
    nfb[:] = 0.0
    for k in range(n_ema):
        xm = _sample_lvdt(par, st, k, rng)
        st[k, _XM] = xm
        if par[k, P.STANDBY] < 0.5:
            s = int(par[k, P.SURF])
            xfb[s] += xm
            nfb[s] += 1.0
    for k in range(n_ema):
        if par[k, P.STANDBY] > 0.5:
            continue
        s = int(par[k, P.SURF])
        wref = par[k, P.KP_X] * (_lerp(xcmd, j, jn, k, frac) - xfb[s] / nfb[s])
        wmax = par[k, P.WMAX]
        st[k, _WREF] = min(max(wref, -wmax), wmax)


@njit(cache=True, inline="always")
def _speed_loop(par: np.ndarray, st: np.ndarray, k: int, th_m: float, dt_w: float,
                a_wf: float) -> None:
    """Speed PI (leaky, clamped integrator) on the low-passed resolver difference -> i_q
    reference, limited to the drive's current."""
    wraw = (th_m - st[k, _THPREV]) / dt_w
    st[k, _THPREV] = th_m
    st[k, _WF] += a_wf * (wraw - st[k, _WF])
    ew = st[k, _WREF] - st[k, _WF]
    imax = par[k, P.IMAX]
    iw = st[k, _IW] + dt_w * (par[k, P.KI_W] * ew - st[k, _IW] / par[k, P.LEAK_W])
    iw = min(max(iw, -imax), imax)
    st[k, _IW] = iw
    st[k, _IQREF] = min(max(par[k, P.KP_W] * ew + iw, -imax), imax)


@njit(cache=True, inline="always")
def _current_pi(ed: float, eq: float, ud_ff: float, uq_ff: float, int_d: float, int_q: float,
                kp: float, ki: float, umax: float, umax2: float, dt: float
                ) -> tuple[float, float, float, float]:
    """d-q current PI on the errors (``ed``, ``eq``) plus the decoupling feed-forward -> voltage
    reference (u_d, u_q) and the integrators. The vector is limited to the inverter's linear
    range (``umax``, :func:`_period_coefficients`); the integrators hold while it is limited
    (anti-windup)."""
    udr = kp * ed + int_d - ud_ff
    uqr = kp * eq + int_q + uq_ff
    usq = udr * udr + uqr * uqr
    # ``umax2`` is a little below umax^2: below it sqrt(usq) <= umax for sure, and the usual
    # case skips the square root (on the critical path); near the limit the root decides
    if usq <= umax2:
        return udr, uqr, int_d + ki * ed * dt, int_q + ki * eq * dt
    umag = math.sqrt(usq)
    if umag > umax:
        return udr * (umax / umag), uqr * (umax / umag), int_d, int_q
    return udr, uqr, int_d + ki * ed * dt, int_q + ki * eq * dt


# ---- ball screw, link, surface -------------------------------------------------------------


@njit(cache=True, inline="always")
def _screw_friction(tl: float, direction: float, tc: float, eta_d: float, eta_b: float) -> float:
    """Friction torque magnitude for motion in ``direction`` against load torque ``tl``."""
    if direction * tl > 0.0:  # motor drives the load: direct efficiency
        return tc + abs(tl) * (1.0 / eta_d - 1.0)
    return tc + abs(tl) * (1.0 - eta_b)  # load back-drives the screw


@njit(cache=True, inline="always")
def _link_force(dx: float, dv: float, half_gap: float, k: float, c: float) -> tuple[float, float]:
    """Dead-zone spring-damper; returns (total force, spring part) along +x on the surface."""
    if dx > half_gap:
        fs = k * (dx - half_gap)
        f = fs + c * dv
        return (f if f > 0.0 else 0.0), fs
    if dx < -half_gap:
        fs = k * (dx + half_gap)
        f = fs + c * dv
        return (f if f < 0.0 else 0.0), fs
    return 0.0, 0.0


@njit(cache=True, inline="always")
def _rod_position(xnut: float, dx: float, fs: float, bl_s: float, bl: float, k_screw: float
                  ) -> float:
    """Rod (LVDT) position: behind the nut by the screw's share of compliance and play."""
    if fs > 0.0:
        return xnut - fs / k_screw - 0.5 * bl_s
    if fs < 0.0:
        return xnut - fs / k_screw + 0.5 * bl_s
    return xnut - (bl_s / bl) * dx if bl > 0.0 else xnut


@njit(cache=True, inline="always")
def _shaft_speed(w: float, te: float, tl: float, dt_j: float, tc: float, tcs: float,
                 eta_d: float, eta_b: float) -> tuple[float, float, bool]:
    """Motor shaft (rotor + screw) under the motor, link and friction torques, Karnopp stick
    -> (new speed, friction torque, stuck); ``dt_j`` is the step over the inertia, dt / J."""
    net = te - tl
    if w == 0.0:
        direction = 1.0 if net > 0.0 else -1.0
        if abs(net) <= _screw_friction(tl, direction, tcs, eta_d, eta_b):
            return 0.0, 0.0, True
        tf = _screw_friction(tl, direction, tc, eta_d, eta_b)
        return w + dt_j * (net - direction * tf), tf, False
    direction = 1.0 if w > 0.0 else -1.0
    tf = _screw_friction(tl, direction, tc, eta_d, eta_b)
    w_n = w + dt_j * (net - direction * tf)
    if w_n * w < 0.0 or abs(w_n) < 1e-9:
        w_n = 0.0  # friction stops the shaft; breakaway is decided on the next step
    return w_n, tf, False


@njit(cache=True, inline="always")
def _surface_arm(par: np.ndarray, s: int) -> float:
    for k in range(par.shape[0]):
        if int(par[k, P.SURF]) == s:
            return par[k, P.ARM]
    return 0.0


@njit(cache=True, inline="always")
def _surface_step(spar: np.ndarray, s: int, f_aero: float, arm: float, torque: float,
                  delta: np.ndarray, ddelta: np.ndarray, dt: float) -> None:
    """One rigid surface about its hinge: aerodynamic moment of its actuators' shares, the link
    torques and hinge damping (semi-implicit Euler)."""
    m_aero = spar[s, S.N_ACT] * f_aero * arm
    m_net = m_aero + torque - spar[s, S.C_H] * ddelta[s]
    dd = ddelta[s] + dt * m_net / spar[s, S.J]
    ddelta[s] = dd
    delta[s] += dt * dd


# ---- thermal and slow coefficients ---------------------------------------------------------


@njit(cache=True, inline="always")
def _winding_temperature(par: np.ndarray, st: np.ndarray, k: int, div: int, dt_out: float,
                         t_amb: float) -> None:
    """Single-body thermal model over one output period: the period's mean losses against
    conduction to ambient through R_th."""
    tw = st[k, _TW]
    ploss = st[k, _PLOSS] / div
    tw += dt_out * (ploss - (tw - t_amb) / par[k, P.RTH]) / par[k, P.CTH]
    st[k, _TW] = tw
    st[k, _PLOSS] = 0.0


@njit(cache=True, inline="always")
def _period_coefficients(par: np.ndarray, st: np.ndarray, k: int, dt: float, coef: np.ndarray
                         ) -> None:
    """Temperature-dependent R_s, R_on and PM flux (with the DMD loss), the current update's
    decay factors and the reciprocals the step multiplies by, held for one output period. A
    standby channel's windings close on the damping star: ``R_d`` takes the place of R_on."""
    tw = st[k, _TW]
    dtc = tw - par[k, P.TREF]
    coef[k, _C_R] = par[k, P.R0] * (1.0 + par[k, P.ALPHA_CU] * dtc)
    if par[k, P.STANDBY] > 0.5:
        coef[k, _C_RON] = par[k, P.R_DAMP]
    else:
        coef[k, _C_RON] = par[k, P.RON] * (1.0 + par[k, P.ALPHA_ON] * (tw - 25.0))
    coef[k, _C_PSI] = (par[k, P.PSI0] * (1.0 + par[k, P.ALPHA_BR] * dtc)
                       * (1.0 - par[k, P.DMD_H]))
    rt = coef[k, _C_R] + coef[k, _C_RON]
    coef[k, _C_AD] = math.exp(-dt * rt / par[k, P.LD])
    coef[k, _C_AQ] = math.exp(-dt * rt / par[k, P.LQ])
    coef[k, _C_UMAX] = 0.95 * par[k, P.UDC] / math.sqrt(3.0)  # the inverter's linear range
    coef[k, _C_DT_J] = dt / par[k, P.J]
    # (1 - 2^-50) covers the rounding of the square: umax2 < umax^2 exactly
    coef[k, _C_UMAX2] = coef[k, _C_UMAX] * coef[k, _C_UMAX] * (1.0 - 2.0 ** -50)


# ---- accounting ----------------------------------------------------------------------------


@njit(cache=True, inline="always")
def _accumulate(acc: np.ndarray, k: int, dt: float, ud: float, uq: float, id_mid: float,
                iq_mid: float, p_cu: float, p_fault: float, tf: float, tl: float, f: float,
                rr: float, wm: float, vatt: float) -> None:
    """Energy audit and the wear drivers' sliding work, integrated every step."""
    acc[k, A.E_IN] += dt * (1.5 * (ud * id_mid + uq * iq_mid))
    acc[k, A.E_CU] += dt * p_cu
    acc[k, A.E_FRIC] += dt * tf * abs(wm)
    acc[k, A.E_LINK] += dt * tl * wm
    acc[k, A.E_FAULT] += dt * p_fault
    acc[k, A.WORK_SCREW] += dt * abs(f) * abs(rr * wm)
    acc[k, A.TRAVEL] += dt * abs(rr * wm)
    acc[k, A.WORK_ROD] += dt * abs(f) * abs(vatt)


@njit(cache=True, inline="always")
def _record_truth(acc: np.ndarray, dbg: np.ndarray, j: int, k: int, tw: float, f: float,
                  id_: float, iq: float, id_mid: float, iq_mid: float, w: float, xrod: float,
                  te: float, iqref: float) -> None:
    """Flight-summary sums and the true states at an output instant."""
    acc[k, A.TW_SUM] += tw
    acc[k, A.TW_MAX] = max(acc[k, A.TW_MAX], tw)
    acc[k, A.F2_SUM] += f * f
    acc[k, A.I2_SUM] += id_ * id_ + iq * iq
    acc[k, A.N] += 1.0
    dbg[j, k, D.ID] = id_mid
    dbg[j, k, D.IQ] = iq_mid
    dbg[j, k, D.W] = w
    dbg[j, k, D.TW] = tw
    dbg[j, k, D.F] = f
    dbg[j, k, D.XROD] = xrod
    dbg[j, k, D.TE] = te
    dbg[j, k, D.IQREF] = iqref


# ---- wiring --------------------------------------------------------------------------------


@njit(cache=True)
def simulate_motor(u_dq: np.ndarray, r: float, ld: float, lq: float, psi: float, pp: float,
                   j: float, b_visc: float, t_load: float, out: np.ndarray) -> None:
    """Motor-only bench with the kernel's PMSM functions: voltages ``u_dq`` (n, 2) [V] held for
    one 12 kHz step each, load ``t_load + b_visc w`` [N m]; writes i_d, i_q, w_m into ``out``."""
    dt = 1.0 / STEP_HZ
    ad = math.exp(-dt * r / ld)
    aq = math.exp(-dt * r / lq)
    id_ = 0.0
    iq = 0.0
    w = 0.0
    w_prev = 0.0
    for n in range(u_dq.shape[0]):
        # speed at mid-step, extrapolated from the last step (as in the kernel)
        w_mid = 1.5 * w - 0.5 * w_prev
        w_prev = w
        id_n, iq_n = _pmsm_currents(id_, iq, u_dq[n, 0], u_dq[n, 1], pp * w_mid, r, ld,
                                    lq, psi, 0.0, ad, aq)
        # torque at mid-step current (as in the kernel)
        te = _pmsm_torque(0.5 * (id_ + id_n), 0.5 * (iq + iq_n), pp, ld, lq, psi)
        id_, iq = id_n, iq_n
        w += dt * (te - t_load - b_visc * w) / j
        out[n, 0] = id_
        out[n, 1] = iq
        out[n, 2] = w


@njit(cache=True, inline="always")
def _initial_state(par: np.ndarray, xcmd: np.ndarray, st: np.ndarray, delta: np.ndarray,
                   acc: np.ndarray) -> None:
    """At rest at the first command; each surface at the mean of its actuators' commands."""
    for s in range(delta.shape[0]):
        cnt = 0.0
        for k in range(par.shape[0]):
            if int(par[k, P.SURF]) == s:
                delta[s] += xcmd[0, k] / par[k, P.ARM]
                cnt += 1.0
        if cnt > 0.0:
            delta[s] /= cnt
    for k in range(par.shape[0]):
        st[k, _TH] = xcmd[0, k] / par[k, P.R_SCREW]
        st[k, _THPREV] = st[k, _TH]
        st[k, _TW] = par[k, P.T0_W]
        duty = 0.0 if par[k, P.STANDBY] > 0.5 else 0.5  # a standby leg never switches
        st[k, _DA] = duty
        st[k, _DB] = duty
        st[k, _DC] = duty
        st[k, _XM] = xcmd[0, k]
        st[k, _XROD] = xcmd[0, k]
        acc[k, A.TW_MAX] = -1e9


@njit(cache=True, error_model="numpy", fastmath=_FASTMATH)
def simulate(
    par: np.ndarray,
    spar: np.ndarray,
    xcmd: np.ndarray,
    fext: np.ndarray,
    tamb: np.ndarray,
    seeds: np.ndarray,
    out: np.ndarray,
    surf_out: np.ndarray,
    dbg: np.ndarray,
    acc: np.ndarray,
) -> None:
    """Run the half-wing for ``xcmd.shape[0]`` output samples.

    par (n_ema, N_PAR), spar (n_surf, N_SURF_PAR), xcmd (n_out, n_ema) [m], fext (n_out, n_surf)
    [N per actuator along +x], tamb (n_out,) [degC], seeds (n_ema,) uint64 non-zero.
    Writes out (n_out, n_ema, 8), surf_out (n_out, n_surf) [rad], dbg (n_out, n_ema, N_DBG),
    acc (n_ema, N_ACC).
    """
    n_out = xcmd.shape[0]
    n_ema = par.shape[0]
    n_surf = spar.shape[0]
    div = int(STEP_HZ / OUT_HZ + 0.5)
    dt = 1.0 / STEP_HZ
    dt_w = dt * SPEED_DIV
    dt_out = dt * div
    rng = seeds.copy()
    st = np.zeros((n_ema, _NST))
    coef = np.zeros((n_ema, _NCOEF))
    delta = np.zeros(n_surf)
    ddelta = np.zeros(n_surf)
    torque_surf = np.zeros(n_surf)
    arm_surf = np.zeros(n_surf)
    for s in range(n_surf):
        arm_surf[s] = _surface_arm(par, s)
    xfb = np.zeros(n_surf)  # consolidated LVDT position per surface
    nfb = np.zeros(n_surf)
    fracs = np.empty(div)  # sub / div, the position within the output period
    for sub in range(div):
        fracs[sub] = sub / div
    a_wf = 1.0 - math.exp(-dt_w * 2.0 * math.pi * 1000.0)  # speed-estimate low-pass
    _initial_state(par, xcmd, st, delta, acc)

    # Helpers that take arrays are straight-line code, helpers with branches take and return
    # scalars: inlining an array argument adds an incref/decref pair, which numba prunes within
    # straight-line code but not always across branches, and a pair left in this loop costs two
    # atomic operations per step.
    for step in range(n_out * div):
        j = step // div
        sub = step - j * div
        frac = fracs[sub]
        jn = j + 1 if j + 1 < n_out else j
        record = sub == 0
        if record:
            for k in range(n_ema):
                if step > 0:
                    _winding_temperature(par, st, k, div, dt_out, tamb[j])
                _period_coefficients(par, st, k, dt, coef)
        for s in range(n_surf):
            torque_surf[s] = 0.0
        if step % POS_DIV == 0:
            _position_loop(par, st, xcmd, j, jn, frac, rng, xfb, nfb)

        for k in range(n_ema):
            pp = par[k, P.PP]
            th = st[k, _TH]
            w = st[k, _W]
            id_ = st[k, _ID]
            iq = st[k, _IQ]
            the = pp * th
            c, sn = _electrical_angle(the, st[k, _THE], st[k, _COS], st[k, _SIN], record)
            st[k, _COS] = c
            st[k, _SIN] = sn
            st[k, _THE] = the
            cb, sb, cc, sc = _phase_axes(c, sn)
            # ---- inverter: apply the duties decided last step ------------------------------
            udc = par[k, P.UDC]
            ron = coef[k, _C_RON]
            da = st[k, _DA]
            db = st[k, _DB]
            dc = st[k, _DC]
            standby = par[k, P.STANDBY] > 0.5
            leg = int(par[k, P.BDO_LEG])
            if leg >= 0 and not standby:
                st[k, _BDOPOS] = _current_sign_held(st[k, _IA + leg], st[k, _BDOPOS])
                da, db, dc = _open_leg_duties(leg, st[k, _BDOPOS], par[k, P.BDO_UPPER], da, db,
                                              dc)
            ua, ub, uc, vcm = _phase_voltages(da, db, dc, udc, ron, st[k, _IA], st[k, _IB],
                                              st[k, _IC])
            # the conduction drop is inside the pole voltage; the motor sees the phase voltage
            # plus the drop's own share, so R_on is lumped with R_s in the current update
            vd, vq = _park(ua, ub, uc, c, sn, cb, sb, cc, sc)
            ud = vd + ron * id_
            uq = vq + ron * iq
            # ---- PMSM: flux, faults, terminal currents --------------------------------------
            rs = coef[k, _C_R]
            psi, dpsi_dt = _eccentric_flux(coef[k, _C_PSI], par[k, P.SE_EPS], par[k, P.SE_PHI],
                                           th, w)
            we = pp * (1.5 * w - 0.5 * st[k, _WPREV])  # mid-step speed, extrapolated
            st[k, _WPREV] = w
            rt = rs + ron
            v_frame = 0.0 if standby else vcm + 0.5 * ua
            dlt, i0, p_fault = _turn_short(par[k, P.TTS_SIGMA], par[k, P.TTS_RF],
                                           par[k, P.TTS_G], ud - rt * id_, uq - rt * iq, c, sn,
                                           rs, v_frame)
            ia, ib, ic = _terminal_currents(id_, iq, c, sn, cb, sb, dlt, i0)
            st[k, _IA] = ia
            st[k, _IB] = ib
            st[k, _IC] = ic
            # ---- sensors; the controller's frame is the true one rotated by the resolver error
            ia_m, ib_m, ic_m = _sample_currents(par, k, rng, ia, ib, ic)
            th_m = _clamp(_measure(th, par[k, P.N_TH], par[k, P.LSB_TH], rng, k),
                          par[k, P.CL_TH], par[k, P.LO_TH], par[k, P.HI_TH])
            cm, sm = _rotate_small(c, sn, pp * (th_m - th))
            cbm, sbm, ccm, scm = _phase_axes(cm, sm)
            id_m, iq_m = _park(ia_m, ib_m, ic_m, cm, sm, cbm, sbm, ccm, scm)
            if record:
                _record_signals(out, j, k, par, rng, ia_m, ib_m, ic_m, ua, ub, uc, th_m)
            # ---- speed loop (4 kHz; the position loop ran before the EMA loop) --------------
            if step % SPEED_DIV == 0 and not standby:
                _speed_loop(par, st, k, th_m, dt_w, a_wf)
            if record:  # LVDT sampled at the recording instant (the loop samples it at 1 kHz)
                out[j, k, 7] = _sample_lvdt(par, st, k, rng)
            # ---- current loop (12 kHz) -> duties for the next step (a standby leg stays at 0)
            if not standby:
                lh = par[k, P.LHAT]
                weh = pp * st[k, _WF]  # decoupling on the controller's own speed and parameters
                udr, uqr, st[k, _ICD], st[k, _ICQ] = _current_pi(
                    -id_m, st[k, _IQREF] - iq_m, weh * lh * iq_m,
                    weh * (lh * id_m + par[k, P.PSIHAT]), st[k, _ICD], st[k, _ICQ],
                    par[k, P.KP_I], par[k, P.KI_I], coef[k, _C_UMAX], coef[k, _C_UMAX2], dt)
                st[k, _DA], st[k, _DB], st[k, _DC] = _svm_duties(udr, uqr, cm, sm, cbm, sbm,
                                                                 udc)
            # ---- PMSM electrical update (exact for frozen speed), torque at mid-step --------
            ld = par[k, P.LD]
            lq = par[k, P.LQ]
            id_n, iq_n = _pmsm_currents(id_, iq, ud, uq, we, rt, ld, lq, psi,
                                        dpsi_dt, coef[k, _C_AD], coef[k, _C_AQ])
            id_mid = 0.5 * (id_ + id_n)
            iq_mid = 0.5 * (iq + iq_n)
            te = _pmsm_torque(id_mid, iq_mid, pp, ld, lq, psi)
            # ---- link (screw + rod end), screw friction and motor shaft ---------------------
            s_idx = int(par[k, P.SURF])
            rr = par[k, P.R_SCREW]
            arm = par[k, P.ARM]
            xnut = rr * th
            vatt = arm * ddelta[s_idx]
            bl_s = par[k, P.BL_SCREW]
            bl = bl_s + par[k, P.BL_ROD]
            dx = xnut - arm * delta[s_idx]
            f, fs = _link_force(dx, rr * w - vatt, 0.5 * bl, par[k, P.K_EQ], par[k, P.C_EQ])
            xrod = _rod_position(xnut, dx, fs, bl_s, bl, par[k, P.K_SCREW])
            st[k, _XROD] = xrod
            torque_surf[s_idx] += arm * f
            tl = rr * f
            w_n, tf, stuck = _shaft_speed(w, te, tl, coef[k, _C_DT_J], par[k, P.TC],
                                          par[k, P.TCS], par[k, P.ETA_D], par[k, P.ETA_B])
            st[k, _W] = w_n
            st[k, _TH] = th + dt * w_n
            st[k, _ID] = id_n
            st[k, _IQ] = iq_n
            # ---- losses (the thermal model's input) and accounting --------------------------
            i2 = id_mid * id_mid + iq_mid * iq_mid
            st[k, _PLOSS] += 1.5 * rs * i2 + p_fault
            _accumulate(acc, k, dt, ud, uq, id_mid, iq_mid, 1.5 * rt * i2, p_fault, tf, tl, f,
                        rr, 0.5 * (w + w_n), vatt)
            if stuck:
                acc[k, A.STILL_S] += dt
            if record:
                _record_truth(acc, dbg, j, k, st[k, _TW], f, id_, iq, id_mid, iq_mid, w, xrod,
                              te, st[k, _IQREF])

        for s in range(n_surf):
            _surface_step(spar, s, _lerp(fext, j, jn, s, frac), arm_surf[s], torque_surf[s],
                          delta, ddelta, dt)
            if record:
                surf_out[j, s] = delta[s]


def warm_up() -> None:
    """Compile the kernel (or load it from the numba cache) with a tiny run."""
    from .params import N_PAR, N_SURF_PAR

    par = np.zeros((1, N_PAR))
    par[0, P.R0], par[0, P.LD], par[0, P.LQ], par[0, P.PSI0], par[0, P.PP] = (
        1.0, 1e-3, 1e-3, 0.05, 4)
    par[0, P.J], par[0, P.UDC], par[0, P.R_SCREW], par[0, P.ETA_D], par[0, P.ETA_B] = (
        1e-4, 270.0, 8e-4, 0.9, 0.9)
    par[0, P.K_EQ], par[0, P.K_SCREW], par[0, P.ARM], par[0, P.RTH], par[0, P.CTH] = (
        1e7, 1e7, 0.04, 1.0, 1000.0)
    par[0, P.LEAK_W], par[0, P.LSB_I], par[0, P.LSB_V], par[0, P.LSB_TH], par[0, P.LSB_X] = (
        1.0, 0.01, 0.1, 1e-4, 1e-6)
    par[0, P.BDO_LEG], par[0, P.IMAX], par[0, P.WMAX] = -1.0, 10.0, 100.0
    spar = np.ones((1, N_SURF_PAR))
    n = 4
    simulate(par, spar, np.zeros((n, 1)), np.zeros((n, 1)), np.zeros(n),
             np.ones(1, dtype=np.uint64), np.zeros((n, 1, N_SIG)), np.zeros((n, 1)),
             np.zeros((n, 1, N_DBG)), np.zeros((1, N_ACC)))
