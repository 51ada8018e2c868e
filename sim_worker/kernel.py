"""The real-time half-wing model: one numba kernel over float64 arrays, several flights at
once in SIMD lanes.

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

Lanes: :func:`simulate` runs up to ``MAX_LANES`` independent flights, one per lane. Every state,
parameter and input array has the lane innermost; a step is a few stages (:func:`_plant_stage`,
:func:`_drive_stage`, the surfaces; the speed and position loops and the output instant's
recording when they tick), each a loop over the lanes of one EMA whose body has no branch
(the Karnopp stick, the backlash dead zone, the saturations, the inverter's open leg and a
standby channel's idle loops are selects) and no call, so LLVM runs it in SIMD registers
(8 float64 lanes with AVX-512). What all lanes do at once (an output instant, a loop tick) is
decided between the stages; what only needs libm (the exact angle, the period's
coefficients, an eccentric motor's flux) runs in loops of its own. Flights of different
lengths share a call: a lane runs on its last input sample after its flight's end, and its
accumulators are taken at that end. A lone flight's lane loops are compiled once more with
one lane known to the compiler, as straight code. Each lane does the operations a scalar
kernel would, in the same order: outputs are bit-identical whatever the lane count or a
flight's neighbours (tests/sim/test_kernel_lanes.py). Two things keep them so: a product
feeding a sum that the scalar code contracts into one FMA but that the vectorised loop would
share between two sums is an explicit FMA (:func:`_fma`), and a value one stage hands to the
next through memory is never a product the scalar code would have fused into the next
stage's sum.

The helpers are compiled with ``inline="always"``: numba inlines them into their stage before
type inference. Helpers called in a lane loop take and return scalars: an array argument would
bring an incref/decref pair into the loop, a call the loop vectoriser cannot vectorise. The
compiled functions are compiled with ``fastmath={"contract", "arcp"}``, which also governs the
inlined helpers: a multiply and an add may fuse into one FMA, and a division may become a
multiplication by the reciprocal. Those two keep IEEE semantics for NaN and infinities (no
``nnan``/``ninf``) and never reorder a sum (no ``reassoc``). The outputs are deterministic for
one machine and CPU build; the last bits differ from a strict-IEEE build's and, through FMA,
from a CPU without fused multiply-add.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from enum import IntEnum
from typing import cast

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.core import cgutils
from numba.extending import intrinsic

from .params import N_PAR, OUT_HZ, POS_DIV, SPEED_DIV, STEP_HZ, P, S

__all__ = ["MAX_LANES", "simulate", "simulate_motor", "warm_up", "A", "N_ACC", "D", "N_DBG",
           "N_SIG"]

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

# Layout of the working array ``st`` (rows, lanes): one block of _NROW rows per EMA, then one of
# _NSROW rows per surface. Every row holds one quantity for every lane, so the lane loop reads
# and writes contiguous memory at offsets that differ by whole rows.
# per-EMA states
_ID, _IQ, _TH, _W, _TW, _IW, _WREF, _IQREF, _ICD, _ICQ = range(10)
_DA, _DB, _DC, _WF, _THPREV, _BDOPOS, _IA, _IB, _IC, _UA = range(10, 20)
_UB, _UC, _VCM, _PLOSS, _XM, _XROD, _WPREV, _COS, _SIN, _THE = range(20, 30)
# per-EMA coefficients held for one output period (temperature dependent)
_C_R, _C_RON, _C_PSI, _C_AD, _C_AQ = range(30, 35)
# and per-EMA limits the step would otherwise recompute (with a division or a square) every step
_C_UMAX, _C_DT_J, _C_UMAX2 = range(35, 38)
_ACC0 = 38  # the accumulators, rows _ACC0 + A.*
# values one stage of a step hands to the next (see simulate)
_S_C, _S_SN, _S_UD, _S_UQ, _S_PSI, _S_DPSI, _S_WE, _S_PFAULT = range(52, 60)
_S_IAM, _S_IBM, _S_ICM, _S_THM = range(60, 64)
_S_F, _S_ID0, _S_IQ0, _S_IDMID, _S_IQMID, _S_W0, _S_TE = range(64, 71)
_S_DELTA, _S_DDELTA = range(71, 73)  # the EMA's surface: deflection and rate (copies)
_NROW = 73
# per-surface rows
_DELTA, _DDELTA, _TORQUE, _ARM_S, _XFB, _NFB = range(6)
_NSROW = 6
#: the most flights one kernel call runs; a row of ``st`` holds this many lanes whatever the
#: batch, so that rows lie a constant distance apart and the compiler can prove that a lane
#: loop's reads and writes of different rows never overlap (with a distance it only learns at
#: run time it would keep the loop scalar)
MAX_LANES = 16


@njit(cache=True, inline="always")
def _at(row: int, ln: int) -> np.uint64:
    """Index into the flat working array ``st`` of quantity ``row``, lane ``ln``; unsigned,
    so that numba adds no wrap-around of negative indices, a select that would hide from the
    compiler that the lane loop walks the row contiguously."""
    return np.uint64(row * MAX_LANES + ln)


@intrinsic
def _fma_intrinsic(typingctx, a, b, c):  # type: ignore[no-untyped-def]
    """``a * b + c`` rounded once (llvm.fma): where the scalar code contracts a product and a
    sum into one FMA but the vectorised lane loop, having merged both sides of a branch into
    one block, would share the product between two sums and round it, the kernel says FMA."""
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):  # type: ignore[no-untyped-def]
        f64 = ir.DoubleType()
        fn = cgutils.get_or_insert_function(  # type: ignore[no-untyped-call]
            builder.module, ir.FunctionType(f64, [f64] * 3), "llvm.fma.f64")
        return builder.call(fn, args)

    return sig, codegen


_fma = cast(Callable[[float, float, float], float], _fma_intrinsic)


@njit(cache=True, inline="always")
def _xorshift(x: np.uint64) -> np.uint64:
    """The next state of a xorshift64 generator."""
    x ^= x << np.uint64(13)
    x ^= x >> np.uint64(7)
    x ^= x << np.uint64(17)
    return x


@njit(cache=True, inline="always")
def _noise(x: np.uint64) -> tuple[float, np.uint64]:
    """Zero-mean unit-variance noise (triangular, sum of two uniforms) from generator state
    ``x`` -> (noise, next state).

    Each draw is the state's top 53 bits, a uniform in [0, 1) times 2^53. The two uniforms are
    added as integers and converted once: both are multiples of 2^-53, so the float sum of the
    two uniforms rounds exactly as the conversion of the integer sum."""
    x1 = _xorshift(x)
    x2 = _xorshift(x1)
    b = (x1 >> np.uint64(11)) + (x2 >> np.uint64(11))
    return (float(b) * (1.0 / 9007199254740992.0) - 1.0) * 2.449489742783178, x2


@njit(cache=True, inline="always")
def _quant(v: float, lsb: float) -> float:
    """``v`` rounded to the nearest multiple of ``lsb``. np.floor keeps the value a float
    (math.floor returns an int in numba: two extra conversions on the critical path; the same
    value for any finite ``v``)."""
    return np.floor(v / lsb + 0.5) * lsb


# ---- sensors -------------------------------------------------------------------------------


@njit(cache=True, inline="always")
def _clamp(v: float, on: float, lo: float, hi: float) -> float:
    """A failed sensor's reading: held in [lo, hi] when its clamp is on (stuck: lo == hi;
    clipped: +-level), after noise and quantisation, where a saturated or frozen converter
    output sits; the controller reads it as it is."""
    return min(max(v, lo), hi) if on > 0.5 else v


# ---- frames --------------------------------------------------------------------------------


@njit(cache=True, inline="always")
def _electrical_angle(the: float, the_prev: float, c_prev: float, s_prev: float, exact: bool
                      ) -> tuple[float, float]:
    """cos and sin of the electrical angle ``the``: exact when ``exact`` (once per output period,
    which bounds the drift: :func:`_exact_angle` wrote them into ``c_prev``, ``s_prev``),
    otherwise the previous step's pair rotated by the small increment."""
    if exact:
        return c_prev, s_prev
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
def _open_leg_duties(leg: float, positive: float, upper_open: float, da: float, db: float,
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
    """Dead-zone spring-damper; returns (total force, spring part) along +x on the surface.
    (``fs + c dv`` as one FMA on either side: see :func:`_fma`.)"""
    extended = dx > half_gap
    fs = k * ((dx - half_gap) if extended else (dx + half_gap))
    f = _fma(c, dv, fs)
    if extended:
        return (f if f > 0.0 else 0.0), fs
    if dx < -half_gap:
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


# ---- lanes ---------------------------------------------------------------------------------
#
# Each stage below is a loop over the lanes of one EMA (or surface), the lane innermost, whose
# body reads and writes the arrays directly and calls helpers that take and return scalars only:
# numba inlines an array argument with an incref/decref pair, a call the loop vectoriser cannot
# vectorise (the pair is pruned only after it ran). A lane's branches are selects
# (:func:`_held`), so the compiler runs the lanes in SIMD registers.


@njit(cache=True, inline="always")
def _held(new: float, old: float, keep: bool) -> float:
    """``old`` where ``keep``, else ``new``: a state a lane leaves alone (a select, no
    branch)."""
    return old if keep else new


@njit(cache=True, inline="always")
def _reading(v: float, noise_rms: float, lsb: float, on: float, lo: float, hi: float,
             x: np.uint64) -> tuple[float, np.uint64]:
    """One sensor reading: ``v`` (offset already added) plus noise from generator state ``x``,
    quantised to the sensor's LSB, held by a failed sensor's clamp -> (reading, next state)."""
    n, x = _noise(x)
    return _clamp(_quant(v + noise_rms * n, lsb), on, lo, hi), x


@njit(cache=True, error_model="numpy", fastmath=_FASTMATH, inline="always")
def _period_start(par: np.ndarray, st: np.ndarray, n_ema: int, tamb: np.ndarray, j: int,
                  div: int, dt: float, first: bool, lanes: int) -> None:
    """At an output instant: each winding's temperature over the period that ended (single
    body: the period's mean losses against conduction to ambient through R_th); the next
    period's temperature-dependent R_s, R_on and PM flux (with the DMD loss), the current
    update's decay factors and the limits the step would otherwise recompute; the exact
    electrical angle. A standby channel's windings close on the damping star: ``R_d`` takes the
    place of R_on."""
    dt_out = dt * div
    for k in range(n_ema):
        pk = k * N_PAR
        ek = k * _NROW
        for ln in range(lanes):
            tw = st[_at(ek + _TW, ln)]
            if not first:
                ploss = st[_at(ek + _PLOSS, ln)] / div
                tw += dt_out * (ploss - (tw - tamb[j, ln]) / par[pk + P.RTH, ln]) / par[
                    pk + P.CTH, ln]
                st[_at(ek + _TW, ln)] = tw
                st[_at(ek + _PLOSS, ln)] = 0.0
            dtc = tw - par[pk + P.TREF, ln]
            rs = par[pk + P.R0, ln] * (1.0 + par[pk + P.ALPHA_CU, ln] * dtc)
            ron = _held(par[pk + P.RON, ln] * (1.0 + par[pk + P.ALPHA_ON, ln] * (tw - 25.0)),
                        par[pk + P.R_DAMP, ln], par[pk + P.STANDBY, ln] > 0.5)
            st[_at(ek + _C_R, ln)] = rs
            st[_at(ek + _C_RON, ln)] = ron
            psi = (par[pk + P.PSI0, ln] * (1.0 + par[pk + P.ALPHA_BR, ln] * dtc)
                   * (1.0 - par[pk + P.DMD_H, ln]))
            st[_at(ek + _C_PSI, ln)] = psi
            # the flux the step uses, unless the motor is eccentric (_eccentric_pass)
            st[_at(ek + _S_PSI, ln)] = psi
            st[_at(ek + _S_DPSI, ln)] = 0.0
            rt = rs + ron
            st[_at(ek + _C_AD, ln)] = math.exp(-dt * rt / par[pk + P.LD, ln])
            st[_at(ek + _C_AQ, ln)] = math.exp(-dt * rt / par[pk + P.LQ, ln])
            umax = 0.95 * par[pk + P.UDC, ln] / math.sqrt(3.0)  # the inverter's linear range
            st[_at(ek + _C_UMAX, ln)] = umax
            st[_at(ek + _C_DT_J, ln)] = dt / par[pk + P.J, ln]
            # (1 - 2^-50) covers the rounding of the square: umax2 < umax^2 exactly
            st[_at(ek + _C_UMAX2, ln)] = umax * umax * (1.0 - 2.0 ** -50)
            the = par[pk + P.PP, ln] * st[_at(ek + _TH, ln)]
            st[_at(ek + _COS, ln)] = math.cos(the)
            st[_at(ek + _SIN, ln)] = math.sin(the)


@njit(cache=True, error_model="numpy", fastmath=_FASTMATH, inline="always")
def _eccentric_pass(par: np.ndarray, st: np.ndarray, n_ema: int, lanes: int) -> None:
    """PM flux and its derivative of the lanes whose motor has a static eccentricity (libm
    calls, so outside the vectorised stages; the other lanes keep the period's flux)."""
    for k in range(n_ema):
        pk = k * N_PAR
        ek = k * _NROW
        for ln in range(lanes):
            eps = par[pk + P.SE_EPS, ln]
            if eps != 0.0:
                psi, dpsi = _eccentric_flux(st[_at(ek + _C_PSI, ln)], eps,
                                            par[pk + P.SE_PHI, ln], st[_at(ek + _TH, ln)],
                                            st[_at(ek + _W, ln)])
                st[_at(ek + _S_PSI, ln)] = psi
                st[_at(ek + _S_DPSI, ln)] = dpsi


@njit(cache=True, error_model="numpy", fastmath=_FASTMATH, inline="always")
def _position_loop(par: np.ndarray, st: np.ndarray, rng: np.ndarray, xcmd: np.ndarray,
                   surf_of: np.ndarray, n_surf: int, j: int, jn: int, frac: float, lanes: int
                   ) -> None:
    """Position P on the consolidated LVDT of each surface: the mean of its active channels'
    LVDTs (two active winglet channels exchange their measurements, which avoids force fight;
    a standby channel's LVDT is sampled but not fed back)."""
    n_ema = surf_of.shape[0]
    s0 = n_ema * _NROW
    for s in range(n_surf):
        for ln in range(lanes):
            st[_at(s0 + s * _NSROW + _XFB, ln)] = 0.0
            st[_at(s0 + s * _NSROW + _NFB, ln)] = 0.0
    for k in range(n_ema):
        pk = k * N_PAR
        ek = k * _NROW
        sb = s0 + surf_of[k] * _NSROW
        for ln in range(lanes):
            xm, rng[k, ln] = _reading(
                st[_at(ek + _XROD, ln)] + par[pk + P.OFF_X, ln], par[pk + P.N_X, ln],
                par[pk + P.LSB_X, ln], par[pk + P.CL_X, ln], par[pk + P.LO_X, ln],
                par[pk + P.HI_X, ln], rng[k, ln])
            st[_at(ek + _XM, ln)] = xm
            standby = par[pk + P.STANDBY, ln] > 0.5
            xfb = st[_at(sb + _XFB, ln)]
            nfb = st[_at(sb + _NFB, ln)]
            st[_at(sb + _XFB, ln)] = _held(xfb + xm, xfb, standby)
            st[_at(sb + _NFB, ln)] = _held(nfb + 1.0, nfb, standby)
    for k in range(n_ema):
        pk = k * N_PAR
        ek = k * _NROW
        sb = s0 + surf_of[k] * _NSROW
        for ln in range(lanes):
            x_ref = xcmd[j, k, ln] + frac * (xcmd[jn, k, ln] - xcmd[j, k, ln])
            wref = par[pk + P.KP_X, ln] * (x_ref - st[_at(sb + _XFB, ln)]
                                           / st[_at(sb + _NFB, ln)])
            wmax = par[pk + P.WMAX, ln]
            st[_at(ek + _WREF, ln)] = _held(min(max(wref, -wmax), wmax),
                                            st[_at(ek + _WREF, ln)],
                                            par[pk + P.STANDBY, ln] > 0.5)


@njit(cache=True, error_model="numpy", fastmath=_FASTMATH, inline="always")
def _plant_stage(par: np.ndarray, st: np.ndarray, rng: np.ndarray, n_ema: int, record: bool
                 , lanes: int) -> None:
    """First stage of a step: angle, the inverter applying last step's duties, the motor's
    voltages, flux and faults, the terminal currents, and their and the resolver's readings."""
    for k in range(n_ema):
        pk = k * N_PAR
        ek = k * _NROW
        for ln in range(lanes):
            pp = par[pk + P.PP, ln]
            th = st[_at(ek + _TH, ln)]
            w = st[_at(ek + _W, ln)]
            id_ = st[_at(ek + _ID, ln)]
            iq = st[_at(ek + _IQ, ln)]
            the = pp * th
            c, sn = _electrical_angle(the, st[_at(ek + _THE, ln)], st[_at(ek + _COS, ln)],
                                      st[_at(ek + _SIN, ln)], record)
            st[_at(ek + _COS, ln)] = c
            st[_at(ek + _SIN, ln)] = sn
            st[_at(ek + _THE, ln)] = the
            cb, sb, cc, sc = _phase_axes(c, sn)
            # ---- inverter: apply the duties decided last step --------------------------------
            udc = par[pk + P.UDC, ln]
            ron = st[_at(ek + _C_RON, ln)]
            ia_prev = st[_at(ek + _IA, ln)]
            ib_prev = st[_at(ek + _IB, ln)]
            ic_prev = st[_at(ek + _IC, ln)]
            standby = par[pk + P.STANDBY, ln] > 0.5
            leg = par[pk + P.BDO_LEG, ln]
            open_leg = leg >= 0.0 and not standby
            i_leg = ia_prev if leg == 0.0 else (ib_prev if leg == 1.0 else ic_prev)
            held = st[_at(ek + _BDOPOS, ln)]
            positive = _held(_current_sign_held(i_leg, held), held, not open_leg)
            st[_at(ek + _BDOPOS, ln)] = positive
            da = st[_at(ek + _DA, ln)]
            db = st[_at(ek + _DB, ln)]
            dc = st[_at(ek + _DC, ln)]
            oa, ob, oc = _open_leg_duties(leg, positive, par[pk + P.BDO_UPPER, ln], da, db, dc)
            da = _held(oa, da, not open_leg)
            db = _held(ob, db, not open_leg)
            dc = _held(oc, dc, not open_leg)
            ua, ub, uc, vcm = _phase_voltages(da, db, dc, udc, ron, ia_prev, ib_prev, ic_prev)
            # the conduction drop is inside the pole voltage; the motor sees the phase voltage
            # plus the drop's own share, so R_on is lumped with R_s in the current update
            vd, vq = _park(ua, ub, uc, c, sn, cb, sb, cc, sc)
            ud = vd + ron * id_
            uq = vq + ron * iq
            # ---- PMSM: flux, faults, terminal currents ---------------------------------------
            rs = st[_at(ek + _C_R, ln)]
            we = pp * (1.5 * w - 0.5 * st[_at(ek + _WPREV, ln)])  # mid-step speed, extrapolated
            st[_at(ek + _WPREV, ln)] = w
            rt = rs + ron
            v_frame = _held(vcm + 0.5 * ua, 0.0, standby)
            dlt, i0, p_fault = _turn_short(par[pk + P.TTS_SIGMA, ln], par[pk + P.TTS_RF, ln],
                                           par[pk + P.TTS_G, ln], ud - rt * id_, uq - rt * iq,
                                           c, sn, rs, v_frame)
            ia, ib, ic = _terminal_currents(id_, iq, c, sn, cb, sb, dlt, i0)
            st[_at(ek + _IA, ln)] = ia
            st[_at(ek + _IB, ln)] = ib
            st[_at(ek + _IC, ln)] = ic
            st[_at(ek + _UA, ln)] = ua
            st[_at(ek + _UB, ln)] = ub
            st[_at(ek + _UC, ln)] = uc
            # ---- sensors: the three currents, then the resolver ------------------------------
            ni = par[pk + P.N_I, ln]
            lsb_i = par[pk + P.LSB_I, ln]
            on, lo, hi = par[pk + P.CL_I, ln], par[pk + P.LO_I, ln], par[pk + P.HI_I, ln]
            x = rng[k, ln]
            ia_m, x = _reading(ia + par[pk + P.OFF_IA, ln], ni, lsb_i, on, lo,
                               hi, x)
            ib_m, x = _reading(ib + par[pk + P.OFF_IB, ln], ni, lsb_i, on, lo,
                               hi, x)
            ic_m, x = _reading(ic + par[pk + P.OFF_IC, ln], ni, lsb_i, on, lo,
                               hi, x)
            th_m, x = _reading(th, par[pk + P.N_TH, ln],
                               par[pk + P.LSB_TH, ln], par[pk + P.CL_TH, ln],
                               par[pk + P.LO_TH, ln], par[pk + P.HI_TH, ln], x)
            rng[k, ln] = x
            st[_at(ek + _S_IAM, ln)] = ia_m
            st[_at(ek + _S_IBM, ln)] = ib_m
            st[_at(ek + _S_ICM, ln)] = ic_m
            st[_at(ek + _S_THM, ln)] = th_m
            st[_at(ek + _S_C, ln)] = c
            st[_at(ek + _S_SN, ln)] = sn
            st[_at(ek + _S_UD, ln)] = ud
            st[_at(ek + _S_UQ, ln)] = uq
            st[_at(ek + _S_WE, ln)] = we
            st[_at(ek + _S_PFAULT, ln)] = p_fault


@njit(cache=True, error_model="numpy", fastmath=_FASTMATH, inline="always")
def _record_signals(par: np.ndarray, st: np.ndarray, rng: np.ndarray, n_ema: int,
                    out: np.ndarray, j: int, lanes: int) -> None:
    """Recorded sensor channels 0-6 at an output instant: the currents and the resolver as the
    controller read them, the three phase voltages' readings (the LVDT, channel 7, is sampled
    after the speed loop)."""
    for k in range(n_ema):
        pk = k * N_PAR
        ek = k * _NROW
        for ln in range(lanes):
            nv = par[pk + P.N_V, ln]
            lsb_v = par[pk + P.LSB_V, ln]
            on, lo, hi = par[pk + P.CL_V, ln], par[pk + P.LO_V, ln], par[pk + P.HI_V, ln]
            x = rng[k, ln]
            va, x = _reading(st[_at(ek + _UA, ln)], nv, lsb_v, on, lo, hi, x)
            vb, x = _reading(st[_at(ek + _UB, ln)], nv, lsb_v, on, lo, hi, x)
            vc, x = _reading(st[_at(ek + _UC, ln)], nv, lsb_v, on, lo, hi, x)
            rng[k, ln] = x
            out[ln, j, k, 0] = st[_at(ek + _S_IAM, ln)]
            out[ln, j, k, 1] = st[_at(ek + _S_IBM, ln)]
            out[ln, j, k, 2] = st[_at(ek + _S_ICM, ln)]
            out[ln, j, k, 3] = va
            out[ln, j, k, 4] = vb
            out[ln, j, k, 5] = vc
            out[ln, j, k, 6] = st[_at(ek + _S_THM, ln)]


@njit(cache=True, error_model="numpy", fastmath=_FASTMATH, inline="always")
def _speed_loop(par: np.ndarray, st: np.ndarray, n_ema: int, dt_w: float, a_wf: float
                , lanes: int) -> None:
    """Speed PI (leaky, clamped integrator) on the low-passed resolver difference -> i_q
    reference, limited to the drive's current; a standby channel's loop does not run."""
    for k in range(n_ema):
        pk = k * N_PAR
        ek = k * _NROW
        for ln in range(lanes):
            keep = par[pk + P.STANDBY, ln] > 0.5
            th_m = st[_at(ek + _S_THM, ln)]
            th_prev = st[_at(ek + _THPREV, ln)]
            wraw = (th_m - th_prev) / dt_w
            st[_at(ek + _THPREV, ln)] = _held(th_m, th_prev, keep)
            wf_prev = st[_at(ek + _WF, ln)]
            wf = wf_prev + a_wf * (wraw - wf_prev)
            st[_at(ek + _WF, ln)] = _held(wf, wf_prev, keep)
            ew = st[_at(ek + _WREF, ln)] - wf
            imax = par[pk + P.IMAX, ln]
            iw_prev = st[_at(ek + _IW, ln)]
            iw = iw_prev + dt_w * (par[pk + P.KI_W, ln] * ew - iw_prev / par[pk + P.LEAK_W, ln])
            iw = min(max(iw, -imax), imax)
            st[_at(ek + _IW, ln)] = _held(iw, iw_prev, keep)
            st[_at(ek + _IQREF, ln)] = _held(min(max(par[pk + P.KP_W, ln] * ew + iw, -imax),
                                                 imax), st[_at(ek + _IQREF, ln)], keep)


@njit(cache=True, error_model="numpy", fastmath=_FASTMATH, inline="always")
def _record_lvdt(par: np.ndarray, st: np.ndarray, rng: np.ndarray, n_ema: int,
                 out: np.ndarray, j: int, lanes: int) -> None:
    """The LVDT's reading at an output instant (the position loop samples it at 1 kHz)."""
    for k in range(n_ema):
        pk = k * N_PAR
        ek = k * _NROW
        for ln in range(lanes):
            out[ln, j, k, 7], rng[k, ln] = _reading(
                st[_at(ek + _XROD, ln)] + par[pk + P.OFF_X, ln], par[pk + P.N_X, ln],
                par[pk + P.LSB_X, ln], par[pk + P.CL_X, ln], par[pk + P.LO_X, ln],
                par[pk + P.HI_X, ln], rng[k, ln])


@njit(cache=True, error_model="numpy", fastmath=_FASTMATH, inline="always")
def _drive_stage(par: np.ndarray, st: np.ndarray, n_ema: int, dt: float, lanes: int) -> None:
    """Second stage of a step: the current loop's duties for the next step, the motor's
    current update and torque, the link, the screw's friction and the shaft, the losses and
    the energy audit."""
    for k in range(n_ema):
        pk = k * N_PAR
        ek = k * _NROW
        a0 = ek + _ACC0
        for ln in range(lanes):
            pp = par[pk + P.PP, ln]
            th = st[_at(ek + _TH, ln)]
            w = st[_at(ek + _W, ln)]
            id_ = st[_at(ek + _ID, ln)]
            iq = st[_at(ek + _IQ, ln)]
            c = st[_at(ek + _S_C, ln)]
            sn = st[_at(ek + _S_SN, ln)]
            # the controller's frame is the true one rotated by the resolver error
            cm, sm = _rotate_small(c, sn, pp * (st[_at(ek + _S_THM, ln)] - th))
            cbm, sbm, ccm, scm = _phase_axes(cm, sm)
            id_m, iq_m = _park(st[_at(ek + _S_IAM, ln)], st[_at(ek + _S_IBM, ln)],
                               st[_at(ek + _S_ICM, ln)], cm, sm, cbm, sbm, ccm, scm)
            # ---- current loop (12 kHz) -> duties for the next step (a standby leg stays at 0)
            standby = par[pk + P.STANDBY, ln] > 0.5
            lh = par[pk + P.LHAT, ln]
            weh = pp * st[_at(ek + _WF, ln)]  # decoupling on the controller's own estimates
            icd_prev = st[_at(ek + _ICD, ln)]
            icq_prev = st[_at(ek + _ICQ, ln)]
            udr, uqr, icd, icq = _current_pi(
                -id_m, st[_at(ek + _IQREF, ln)] - iq_m, weh * lh * iq_m,
                weh * (lh * id_m + par[pk + P.PSIHAT, ln]), icd_prev, icq_prev,
                par[pk + P.KP_I, ln], par[pk + P.KI_I, ln], st[_at(ek + _C_UMAX, ln)],
                st[_at(ek + _C_UMAX2, ln)], dt)
            da, db, dc = _svm_duties(udr, uqr, cm, sm, cbm, sbm, par[pk + P.UDC, ln])
            st[_at(ek + _ICD, ln)] = _held(icd, icd_prev, standby)
            st[_at(ek + _ICQ, ln)] = _held(icq, icq_prev, standby)
            st[_at(ek + _DA, ln)] = _held(da, st[_at(ek + _DA, ln)], standby)
            st[_at(ek + _DB, ln)] = _held(db, st[_at(ek + _DB, ln)], standby)
            st[_at(ek + _DC, ln)] = _held(dc, st[_at(ek + _DC, ln)], standby)
            # ---- PMSM electrical update (exact for frozen speed), torque at mid-step --------
            ld = par[pk + P.LD, ln]
            lq = par[pk + P.LQ, ln]
            rs = st[_at(ek + _C_R, ln)]
            rt = rs + st[_at(ek + _C_RON, ln)]
            ud = st[_at(ek + _S_UD, ln)]
            uq = st[_at(ek + _S_UQ, ln)]
            psi = st[_at(ek + _S_PSI, ln)]
            p_fault = st[_at(ek + _S_PFAULT, ln)]
            id_n, iq_n = _pmsm_currents(id_, iq, ud, uq, st[_at(ek + _S_WE, ln)], rt, ld, lq,
                                        psi, st[_at(ek + _S_DPSI, ln)],
                                        st[_at(ek + _C_AD, ln)], st[_at(ek + _C_AQ, ln)])
            id_mid = 0.5 * (id_ + id_n)
            iq_mid = 0.5 * (iq + iq_n)
            te = _pmsm_torque(id_mid, iq_mid, pp, ld, lq, psi)
            # ---- link (screw + rod end), screw friction and motor shaft ---------------------
            rr = par[pk + P.R_SCREW, ln]
            arm = par[pk + P.ARM, ln]
            xnut = rr * th
            vatt = arm * st[_at(ek + _S_DDELTA, ln)]
            bl_s = par[pk + P.BL_SCREW, ln]
            bl = bl_s + par[pk + P.BL_ROD, ln]
            dx = xnut - arm * st[_at(ek + _S_DELTA, ln)]
            f, fs = _link_force(dx, rr * w - vatt, 0.5 * bl, par[pk + P.K_EQ, ln],
                                par[pk + P.C_EQ, ln])
            xrod = _rod_position(xnut, dx, fs, bl_s, bl, par[pk + P.K_SCREW, ln])
            st[_at(ek + _XROD, ln)] = xrod
            tl = rr * f
            w_n, tf, stuck = _shaft_speed(w, te, tl, st[_at(ek + _C_DT_J, ln)],
                                          par[pk + P.TC, ln], par[pk + P.TCS, ln],
                                          par[pk + P.ETA_D, ln], par[pk + P.ETA_B, ln])
            st[_at(ek + _W, ln)] = w_n
            st[_at(ek + _TH, ln)] = th + dt * w_n
            st[_at(ek + _ID, ln)] = id_n
            st[_at(ek + _IQ, ln)] = iq_n
            # ---- losses (the thermal model's input), energy audit, wear drivers' work --------
            i2 = id_mid * id_mid + iq_mid * iq_mid
            st[_at(ek + _PLOSS, ln)] += 1.5 * rs * i2 + p_fault
            wm = 0.5 * (w + w_n)
            st[_at(a0 + A.E_IN, ln)] += dt * (1.5 * (ud * id_mid + uq * iq_mid))
            st[_at(a0 + A.E_CU, ln)] += dt * (1.5 * rt * i2)
            st[_at(a0 + A.E_FRIC, ln)] += dt * tf * abs(wm)
            st[_at(a0 + A.E_LINK, ln)] += dt * tl * wm
            st[_at(a0 + A.E_FAULT, ln)] += dt * p_fault
            st[_at(a0 + A.WORK_SCREW, ln)] += dt * abs(f) * abs(rr * wm)
            st[_at(a0 + A.TRAVEL, ln)] += dt * abs(rr * wm)
            st[_at(a0 + A.WORK_ROD, ln)] += dt * abs(f) * abs(vatt)
            still = st[_at(a0 + A.STILL_S, ln)]
            st[_at(a0 + A.STILL_S, ln)] = _held(still + dt, still, not stuck)
            # what an output instant records (_record_truth)
            st[_at(ek + _S_F, ln)] = f
            st[_at(ek + _S_ID0, ln)] = id_
            st[_at(ek + _S_IQ0, ln)] = iq
            st[_at(ek + _S_IDMID, ln)] = id_mid
            st[_at(ek + _S_IQMID, ln)] = iq_mid
            st[_at(ek + _S_W0, ln)] = w
            st[_at(ek + _S_TE, ln)] = te


@njit(cache=True, error_model="numpy", fastmath=_FASTMATH, inline="always")
def _record_truth(par: np.ndarray, st: np.ndarray, n_ema: int, dbg: np.ndarray, j: int
                  , lanes: int) -> None:
    """Flight-summary sums and, unless ``dbg`` holds no samples, the true states at an output
    instant."""
    for k in range(n_ema):
        ek = k * _NROW
        a0 = ek + _ACC0
        for ln in range(lanes):
            tw = st[_at(ek + _TW, ln)]
            f = st[_at(ek + _S_F, ln)]
            id_ = st[_at(ek + _S_ID0, ln)]
            iq = st[_at(ek + _S_IQ0, ln)]
            st[_at(a0 + A.TW_SUM, ln)] += tw
            st[_at(a0 + A.TW_MAX, ln)] = max(st[_at(a0 + A.TW_MAX, ln)], tw)
            st[_at(a0 + A.F2_SUM, ln)] += f * f
            st[_at(a0 + A.I2_SUM, ln)] += id_ * id_ + iq * iq
            st[_at(a0 + A.N, ln)] += 1.0
        if dbg.shape[1] == 0:
            continue
        for ln in range(lanes):
            dbg[ln, j, k, D.ID] = st[_at(ek + _S_IDMID, ln)]
            dbg[ln, j, k, D.IQ] = st[_at(ek + _S_IQMID, ln)]
            dbg[ln, j, k, D.W] = st[_at(ek + _S_W0, ln)]
            dbg[ln, j, k, D.TW] = st[_at(ek + _TW, ln)]
            dbg[ln, j, k, D.F] = st[_at(ek + _S_F, ln)]
            dbg[ln, j, k, D.XROD] = st[_at(ek + _XROD, ln)]
            dbg[ln, j, k, D.TE] = st[_at(ek + _S_TE, ln)]
            dbg[ln, j, k, D.IQREF] = st[_at(ek + _IQREF, ln)]


@njit(cache=True, error_model="numpy", fastmath=_FASTMATH, inline="always")
def _surfaces(par: np.ndarray, spar: np.ndarray, st: np.ndarray, surf_of: np.ndarray,
              fext: np.ndarray, j: int, jn: int, frac: float, dt: float, surf_out: np.ndarray,
              record: bool, lanes: int) -> None:
    """One step of each rigid surface about its hinge: the aerodynamic moment of its
    actuators' shares, the link torques (summed in EMA order) and hinge damping
    (semi-implicit Euler), recorded at an output instant; then each EMA's copy of its
    surface's deflection and rate."""
    n_ema = surf_of.shape[0]
    n_surf = spar.shape[0]
    s0 = n_ema * _NROW
    for s in range(n_surf):
        for ln in range(lanes):
            st[_at(s0 + s * _NSROW + _TORQUE, ln)] = 0.0
    for k in range(n_ema):
        pk = k * N_PAR
        ek = k * _NROW
        sb = s0 + surf_of[k] * _NSROW
        for ln in range(lanes):
            st[_at(sb + _TORQUE, ln)] += par[pk + P.ARM, ln] * st[_at(ek + _S_F, ln)]
    for s in range(n_surf):
        sb = s0 + s * _NSROW
        for ln in range(lanes):
            f_aero = fext[j, s, ln] + frac * (fext[jn, s, ln] - fext[j, s, ln])
            m_aero = spar[s, S.N_ACT, ln] * f_aero * st[_at(sb + _ARM_S, ln)]
            ddelta = st[_at(sb + _DDELTA, ln)]
            m_net = m_aero + st[_at(sb + _TORQUE, ln)] - spar[s, S.C_H, ln] * ddelta
            dd = ddelta + dt * m_net / spar[s, S.J, ln]
            st[_at(sb + _DDELTA, ln)] = dd
            st[_at(sb + _DELTA, ln)] += dt * dd
        if record:
            for ln in range(lanes):
                surf_out[ln, j, s] = st[_at(sb + _DELTA, ln)]
    for k in range(n_ema):
        ek = k * _NROW
        sb = s0 + surf_of[k] * _NSROW
        for ln in range(lanes):
            st[_at(ek + _S_DELTA, ln)] = st[_at(sb + _DELTA, ln)]
            st[_at(ek + _S_DDELTA, ln)] = st[_at(sb + _DDELTA, ln)]


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


@njit(cache=True)
def _initial_state(par: np.ndarray, xcmd: np.ndarray, surf_of: np.ndarray, st: np.ndarray,
                   n_surf: int) -> None:
    """At rest at the first command; each surface at the mean of its actuators' commands, its
    arm that of its first actuator."""
    n_ema = surf_of.shape[0]
    lanes = par.shape[1]
    s0 = n_ema * _NROW
    for ln in range(lanes):
        for s in range(n_surf):
            sb = s0 + s * _NSROW
            cnt = 0.0
            for k in range(n_ema):
                if surf_of[k] == s:
                    if cnt == 0.0:
                        st[_at(sb + _ARM_S, ln)] = par[k * N_PAR + P.ARM, ln]
                    st[_at(sb + _DELTA, ln)] += xcmd[0, k, ln] / par[k * N_PAR + P.ARM, ln]
                    cnt += 1.0
            if cnt > 0.0:
                st[_at(sb + _DELTA, ln)] /= cnt
        for k in range(n_ema):
            pk = k * N_PAR
            ek = k * _NROW
            st[_at(ek + _TH, ln)] = xcmd[0, k, ln] / par[pk + P.R_SCREW, ln]
            st[_at(ek + _THPREV, ln)] = st[_at(ek + _TH, ln)]
            st[_at(ek + _TW, ln)] = par[pk + P.T0_W, ln]
            duty = 0.0 if par[pk + P.STANDBY, ln] > 0.5 else 0.5  # a standby leg never switches
            st[_at(ek + _DA, ln)] = duty
            st[_at(ek + _DB, ln)] = duty
            st[_at(ek + _DC, ln)] = duty
            st[_at(ek + _XM, ln)] = xcmd[0, k, ln]
            st[_at(ek + _XROD, ln)] = xcmd[0, k, ln]
            st[_at(ek + _ACC0 + A.TW_MAX, ln)] = -1e9
            sb = s0 + surf_of[k] * _NSROW
            st[_at(ek + _S_DELTA, ln)] = st[_at(sb + _DELTA, ln)]


@njit(cache=True)
def _finish_lanes(st: np.ndarray, n_out: np.ndarray, j: int, n_ema: int, acc: np.ndarray
                  ) -> None:
    """Copy the accumulators of the lanes whose flight ends at output sample ``j``."""
    for ln in range(n_out.shape[0]):
        if n_out[ln] == j:
            for k in range(n_ema):
                for a in range(N_ACC):
                    acc[ln, k, a] = st[_at(k * _NROW + _ACC0 + a, ln)]


@njit(cache=True, error_model="numpy", fastmath=_FASTMATH, inline="always")
def _steps(par2: np.ndarray, spar: np.ndarray, st: np.ndarray, rng: np.ndarray,
           xcmd: np.ndarray, fext: np.ndarray, tamb: np.ndarray, n_out: np.ndarray,
           out: np.ndarray, surf_out: np.ndarray, dbg: np.ndarray, acc: np.ndarray,
           surf_of: np.ndarray, any_eccentric: bool, fracs: np.ndarray, a_wf: float,
           lanes: int) -> None:
    """Every 12 kHz step of the flights in lanes. What every lane does at once (an output
    instant, a speed or position loop tick) is decided here, outside the lane loops."""
    n_max = xcmd.shape[0]
    n_ema = surf_of.shape[0]
    n_surf = spar.shape[0]
    div = fracs.shape[0]
    dt = 1.0 / STEP_HZ
    dt_w = dt * SPEED_DIV
    for step in range(n_max * div):
        j = step // div
        sub = step - j * div
        frac = fracs[sub]
        jn = j + 1 if j + 1 < n_max else j
        record = sub == 0
        if record:
            if step > 0:
                _finish_lanes(st, n_out, j, n_ema, acc)
            _period_start(par2, st, n_ema, tamb, j, div, dt, step == 0, lanes)
        if any_eccentric:
            _eccentric_pass(par2, st, n_ema, lanes)
        if step % POS_DIV == 0:
            _position_loop(par2, st, rng, xcmd, surf_of, n_surf, j, jn, frac, lanes)
        _plant_stage(par2, st, rng, n_ema, record, lanes)
        if record:
            _record_signals(par2, st, rng, n_ema, out, j, lanes)
        if step % SPEED_DIV == 0:  # 4 kHz; the position loop ran before the plant stage
            _speed_loop(par2, st, n_ema, dt_w, a_wf, lanes)
        if record:  # LVDT sampled at the recording instant (the loop samples it at 1 kHz)
            _record_lvdt(par2, st, rng, n_ema, out, j, lanes)
        _drive_stage(par2, st, n_ema, dt, lanes)
        if record:
            _record_truth(par2, st, n_ema, dbg, j, lanes)
        _surfaces(par2, spar, st, surf_of, fext, j, jn, frac, dt, surf_out, record, lanes)


@njit(cache=True, error_model="numpy", fastmath=_FASTMATH)
def simulate(
    par: np.ndarray,
    spar: np.ndarray,
    xcmd: np.ndarray,
    fext: np.ndarray,
    tamb: np.ndarray,
    seeds: np.ndarray,
    n_out: np.ndarray,
    out: np.ndarray,
    surf_out: np.ndarray,
    dbg: np.ndarray,
    acc: np.ndarray,
) -> None:
    """Run half-wing flights in lanes: lane ``l`` of every array is one flight, lasting
    ``n_out[l]`` output samples; the arrays run to the longest, ``n = xcmd.shape[0]``.

    par (n_ema, N_PAR, L), spar (n_surf, N_SURF_PAR, L), xcmd (n, n_ema, L) [m],
    fext (n, n_surf, L) [N per actuator along +x], tamb (n, L) [degC], seeds (n_ema, L) uint64
    non-zero, n_out (L,) int64 in [1, n]; a flight's inputs past its end repeat its last sample
    (then a lane runs on after its end exactly as it would have run its last sample).
    Every EMA is on the same surface in every lane (``P.SURF``).
    Writes out (L, n, n_ema, N_SIG), surf_out (L, n, n_surf) [rad], dbg (L, n, n_ema, N_DBG),
    samples past a lane's end unspecified (dbg may hold no samples, (L, 0, n_ema, N_DBG): the
    true states are then not recorded), and acc (L, n_ema, N_ACC), each lane's at its end:
    the outputs are lane-major, one flight's contiguous (written once an output period, they
    cost the lane loops a scattered store, and the caller no transposition of every signal).
    """
    n_max = xcmd.shape[0]
    n_ema = par.shape[0]
    n_surf = spar.shape[0]
    lanes = par.shape[2]
    par2 = par.reshape(n_ema * N_PAR, lanes)
    div = int(STEP_HZ / OUT_HZ + 0.5)
    dt = 1.0 / STEP_HZ
    dt_w = dt * SPEED_DIV
    rng = seeds.copy()
    surf_of = np.empty(n_ema, dtype=np.int64)
    any_eccentric = False
    for k in range(n_ema):
        surf_of[k] = int(par[k, P.SURF, 0])
        for ln in range(lanes):
            any_eccentric = any_eccentric or par[k, P.SE_EPS, ln] != 0.0
    s0 = n_ema * _NROW
    if lanes > MAX_LANES:
        raise ValueError("more lanes than MAX_LANES")
    st = np.zeros((s0 + n_surf * _NSROW) * MAX_LANES)
    fracs = np.empty(div)  # sub / div, the position within the output period
    for sub in range(div):
        fracs[sub] = sub / div
    a_wf = 1.0 - math.exp(-dt_w * 2.0 * math.pi * 1000.0)  # speed-estimate low-pass
    _initial_state(par2, xcmd, surf_of, st, n_surf)

    # a lone flight's lane loops run once: known to the compiler, they are straight code
    if lanes == 1:
        _steps(par2, spar, st, rng, xcmd, fext, tamb, n_out, out, surf_out, dbg, acc, surf_of,
               any_eccentric, fracs, a_wf, 1)
    else:
        _steps(par2, spar, st, rng, xcmd, fext, tamb, n_out, out, surf_out, dbg, acc, surf_of,
               any_eccentric, fracs, a_wf, lanes)
    _finish_lanes(st, n_out, n_max, n_ema, acc)


def warm_up() -> None:
    """Compile the kernel (or load it from the numba cache) with a tiny run."""
    from .params import N_SURF_PAR

    par = np.zeros((1, N_PAR, 1))
    row = par[0, :, 0]
    row[P.R0], row[P.LD], row[P.LQ], row[P.PSI0], row[P.PP] = 1.0, 1e-3, 1e-3, 0.05, 4
    row[P.J], row[P.UDC], row[P.R_SCREW], row[P.ETA_D], row[P.ETA_B] = (
        1e-4, 270.0, 8e-4, 0.9, 0.9)
    row[P.K_EQ], row[P.K_SCREW], row[P.ARM], row[P.RTH], row[P.CTH] = (
        1e7, 1e7, 0.04, 1.0, 1000.0)
    row[P.LEAK_W], row[P.LSB_I], row[P.LSB_V], row[P.LSB_TH], row[P.LSB_X] = (
        1.0, 0.01, 0.1, 1e-4, 1e-6)
    row[P.BDO_LEG], row[P.IMAX], row[P.WMAX] = -1.0, 10.0, 100.0
    spar = np.ones((1, N_SURF_PAR, 1))
    n = 4
    simulate(par, spar, np.zeros((n, 1, 1)), np.zeros((n, 1, 1)), np.zeros((n, 1)),
             np.ones((1, 1), dtype=np.uint64), np.full(1, n), np.zeros((1, n, 1, N_SIG)),
             np.zeros((1, n, 1)), np.zeros((1, n, 1, N_DBG)), np.zeros((1, 1, N_ACC)))
