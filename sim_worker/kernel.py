"""The real-time half-wing model: one flat numba kernel over float64 arrays.

Fixed step ``dt = 1 / 12 kHz``; current PI every step, speed PI every 3 steps (4 kHz), position P
every 12 steps (1 kHz); sensor outputs every 15 steps (800 Hz). Per EMA the states are the d-q
currents (peak, amplitude invariant, magnetising equivalent), rotor angle and speed, winding
temperature and the controller states; per surface the deflection and its rate.

Subsystems, each a small function below, wired once in :func:`simulate`:

* inverter: averaged legs, pole voltage ``d_k U_dc`` minus the conduction drop; min-max zero
  sequence (space-vector equivalent); MOSFET base-drive open changes the effective duty by the
  sign of the leg current (REFERENCE.md inverter faults);
* PMSM in d-q with R(T), psi(T), magnet loss ``(1 - h)``, static eccentricity as a flux modulation
  by the mechanical angle; turn-to-turn short as a shorted loop on phase a (quasi-static) whose
  reflected current and a winding-to-frame leakage enter the terminal currents;
* ball screw: load-dependent friction from the direct/back-driving efficiencies, Karnopp stick;
* link: screw and rod-end compliance and backlash folded into one dead-zone spring with damping;
  the LVDT rod position is recovered from the force through the screw part;
* surface: one rigid body per surface with aerodynamic force input and hinge damping;
* thermal: single body, copper + short-circuit losses, to ambient through R_th;
* sensors: offset, noise (in-kernel xorshift generator seeded from a numpy Generator),
  quantisation.
"""

from __future__ import annotations

import math
from enum import IntEnum

import numpy as np
from numba import njit

from .params import OUT_HZ, POS_DIV, SPEED_DIV, STEP_HZ, P, S

__all__ = ["simulate", "simulate_motor", "warm_up", "A", "N_ACC", "D", "N_DBG", "N_SIG"]

SQRT3_2 = math.sqrt(3.0) / 2.0
N_SIG = 8  # ia ib ic va vb vc theta x


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


@njit(cache=True, inline="always")
def _uniform(rng: np.ndarray, k: int) -> float:
    x = rng[k]
    x ^= x << np.uint64(13)
    x ^= x >> np.uint64(7)
    x ^= x << np.uint64(17)
    rng[k] = x
    return float(x >> np.uint64(11)) * (1.0 / 9007199254740992.0)


@njit(cache=True, inline="always")
def _noise(rng: np.ndarray, k: int) -> float:
    """Zero-mean unit-variance noise (triangular, sum of two uniforms)."""
    return (_uniform(rng, k) + _uniform(rng, k) - 1.0) * 2.449489742783178


@njit(cache=True, inline="always")
def _quant(v: float, lsb: float) -> float:
    return math.floor(v / lsb + 0.5) * lsb


@njit(cache=True, inline="always")
def _leg_duty(d: float, i: float, upper_open: float) -> float:
    """Effective duty of a leg with one MOSFET that never turns on (its diode still conducts)."""
    if upper_open > 0.5:
        return d if i < 0.0 else 0.0
    return 1.0 if i < 0.0 else d


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
def _pmsm_currents(id_: float, iq: float, ud: float, uq: float, we: float, r: float, ld: float,
                   lq: float, psi: float, dpsi_dt: float, ad: float, aq: float
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
    return id_n, iq_n


@njit(cache=True, inline="always")
def _pmsm_torque(id_: float, iq: float, pp: float, ld: float, lq: float, psi: float) -> float:
    return 1.5 * pp * (psi * iq + (ld - lq) * id_ * iq)


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
        id_n, iq_n = _pmsm_currents(id_, iq, u_dq[n, 0], u_dq[n, 1], pp * w_mid, r, ld, lq,
                                    psi, 0.0, ad, aq)
        # torque at mid-step current (as in the kernel)
        te = _pmsm_torque(0.5 * (id_ + id_n), 0.5 * (iq + iq_n), pp, ld, lq, psi)
        id_, iq = id_n, iq_n
        w += dt * (te - t_load - b_visc * w) / j
        out[n, 0] = id_
        out[n, 1] = iq
        out[n, 2] = w


@njit(cache=True, error_model="numpy")
def _position_loop(par: np.ndarray, st: np.ndarray, xcmd: np.ndarray, j: int, jn: int,
                   frac: float, rng: np.ndarray, xfb: np.ndarray, nfb: np.ndarray) -> None:
    """Position P on the consolidated LVDT of each surface (mean of its actuators' LVDTs: the
    two winglet channels exchange their measurements, which avoids force fight)."""
    n_ema = par.shape[0]
    xfb[:] = 0.0
    nfb[:] = 0.0
    for k in range(n_ema):
        xm = _quant(st[k, _XROD] + par[k, P.OFF_X] + par[k, P.N_X] * _noise(rng, k),
                    par[k, P.LSB_X])
        st[k, _XM] = xm
        s = int(par[k, P.SURF])
        xfb[s] += xm
        nfb[s] += 1.0
    for k in range(n_ema):
        s = int(par[k, P.SURF])
        xc = xcmd[j, k] + frac * (xcmd[jn, k] - xcmd[j, k])
        wref = par[k, P.KP_X] * (xc - xfb[s] / nfb[s])
        wmax = par[k, P.WMAX]
        st[k, _WREF] = min(max(wref, -wmax), wmax)


@njit(cache=True, inline="always")
def _surface_arm(par: np.ndarray, s: int) -> float:
    for k in range(par.shape[0]):
        if int(par[k, P.SURF]) == s:
            return par[k, P.ARM]
    return 0.0


@njit(cache=True, error_model="numpy")
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
    n_steps = n_out * div
    rng = seeds.copy()
    st = np.zeros((n_ema, _NST))
    delta = np.zeros(n_surf)
    ddelta = np.zeros(n_surf)
    torque_surf = np.zeros(n_surf)
    arm_surf = np.zeros(n_surf)
    for s in range(n_surf):
        arm_surf[s] = _surface_arm(par, s)
    xfb = np.zeros(n_surf)  # consolidated LVDT position per surface
    nfb = np.zeros(n_surf)
    # per-output-period coefficients
    r_now = np.zeros(n_ema)
    psi_now = np.zeros(n_ema)
    ron_now = np.zeros(n_ema)
    ad = np.zeros(n_ema)
    aq = np.zeros(n_ema)
    a_wf = 1.0 - math.exp(-dt_w * 2.0 * math.pi * 1000.0)  # speed-estimate low-pass
    # initial conditions: at rest at the first command
    for s in range(n_surf):
        cnt = 0.0
        for k in range(n_ema):
            if int(par[k, P.SURF]) == s:
                delta[s] += xcmd[0, k] / par[k, P.ARM]
                cnt += 1.0
        if cnt > 0.0:
            delta[s] /= cnt
    for k in range(n_ema):
        st[k, _TH] = xcmd[0, k] / par[k, P.R_SCREW]
        st[k, _THPREV] = st[k, _TH]
        st[k, _TW] = par[k, P.T0_W]
        st[k, _DA] = 0.5
        st[k, _DB] = 0.5
        st[k, _DC] = 0.5
        st[k, _XM] = xcmd[0, k]
        st[k, _XROD] = xcmd[0, k]
        acc[k, A.TW_MAX] = -1e9

    for step in range(n_steps):
        j = step // div
        sub = step - j * div
        frac = sub / div
        jn = j + 1 if j + 1 < n_out else j
        if sub == 0:
            # slow updates once per output period: temperatures, coefficients, thermal model
            for k in range(n_ema):
                tw = st[k, _TW]
                if step > 0:
                    ploss = st[k, _PLOSS] / div
                    tw += dt_out * (ploss - (tw - tamb[j]) / par[k, P.RTH]) / par[k, P.CTH]
                    st[k, _TW] = tw
                    st[k, _PLOSS] = 0.0
                dtc = tw - par[k, P.TREF]
                r_now[k] = par[k, P.R0] * (1.0 + par[k, P.ALPHA_CU] * dtc)
                ron_now[k] = par[k, P.RON] * (1.0 + par[k, P.ALPHA_ON] * (tw - 25.0))
                psi_now[k] = (par[k, P.PSI0] * (1.0 + par[k, P.ALPHA_BR] * dtc)
                              * (1.0 - par[k, P.DMD_H]))
                rt = r_now[k] + ron_now[k]
                ad[k] = math.exp(-dt * rt / par[k, P.LD])
                aq[k] = math.exp(-dt * rt / par[k, P.LQ])
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
            if sub == 0:  # exact once per output period, rotated in between
                c = math.cos(the)
                sn = math.sin(the)
            else:
                d1 = the - st[k, _THE]
                d2 = d1 * d1
                cd = 1.0 - d2 * (0.5 - d2 * (1.0 / 24.0))
                sd = d1 * (1.0 - d2 * (1.0 / 6.0 - d2 * (1.0 / 120.0)))
                c0 = st[k, _COS]
                s0 = st[k, _SIN]
                c = c0 * cd - s0 * sd
                sn = s0 * cd + c0 * sd
            st[k, _COS] = c
            st[k, _SIN] = sn
            st[k, _THE] = the
            cb = -0.5 * c + SQRT3_2 * sn
            sb = -0.5 * sn - SQRT3_2 * c
            cc = -0.5 * c - SQRT3_2 * sn
            sc = -0.5 * sn + SQRT3_2 * c
            # ---- inverter: apply the duties decided last step ---------------------------------
            udc = par[k, P.UDC]
            da = st[k, _DA]
            db = st[k, _DB]
            dc = st[k, _DC]
            leg = int(par[k, P.BDO_LEG])
            if leg >= 0:
                ileg = st[k, _IA + leg]
                pos = st[k, _BDOPOS]
                if ileg > 0.05:
                    pos = 1.0
                elif ileg < -0.05:
                    pos = 0.0
                st[k, _BDOPOS] = pos
                isign = 1.0 if pos > 0.5 else -1.0
                if leg == 0:
                    da = _leg_duty(da, isign, par[k, P.BDO_UPPER])
                elif leg == 1:
                    db = _leg_duty(db, isign, par[k, P.BDO_UPPER])
                else:
                    dc = _leg_duty(dc, isign, par[k, P.BDO_UPPER])
            ron = ron_now[k]
            va = da * udc - ron * st[k, _IA]
            vb = db * udc - ron * st[k, _IB]
            vc = dc * udc - ron * st[k, _IC]
            vmean = (va + vb + vc) / 3.0
            ua = va - vmean
            ub = vb - vmean
            uc = vc - vmean
            vcm = vmean - 0.5 * udc
            # the conduction drop is inside the pole voltage; the motor sees the phase voltage
            # plus the drop's own share, so R_on is lumped with R_s in the current update
            ud = (2.0 / 3.0) * (ua * c + ub * cb + uc * cc) + ron * id_
            uq = -(2.0 / 3.0) * (ua * sn + ub * sb + uc * sc) + ron * iq
            # ---- PMSM ----------------------------------------------------------------------
            rs = r_now[k]
            psi = psi_now[k]
            eps = par[k, P.SE_EPS]
            dpsi_dt = 0.0
            if eps != 0.0:
                ang = th - par[k, P.SE_PHI]
                psi = psi * (1.0 + eps * math.cos(ang))
                dpsi_dt = -psi_now[k] * eps * math.sin(ang) * w
            we = pp * (1.5 * w - 0.5 * st[k, _WPREV])  # mid-step speed, extrapolated
            st[k, _WPREV] = w
            ld = par[k, P.LD]
            lq = par[k, P.LQ]
            rt = rs + ron
            # terminal currents: magnetising currents + shorted-loop reflection + leakage
            ia0 = id_ * c - iq * sn
            ib0 = id_ * cb - iq * sb
            sig = par[k, P.TTS_SIGMA]
            dlt = 0.0
            i0 = 0.0
            p_fault = 0.0
            if sig > 0.0:
                ed = ud - rt * id_
                eq = uq - rt * iq
                ea = ed * c - eq * sn
                i_f = sig * ea / (par[k, P.TTS_RF] + sig * rs)
                dlt = sig * i_f
                vfault = vcm + 0.5 * ua
                i0 = par[k, P.TTS_G] * vfault
                p_fault = i_f * i_f * (par[k, P.TTS_RF] + sig * rs) + i0 * vfault
            ia = ia0 + (2.0 / 3.0) * dlt + i0
            ib = ib0 - dlt / 3.0
            ic = -ia0 - ib0 - dlt / 3.0
            st[k, _IA] = ia
            st[k, _IB] = ib
            st[k, _IC] = ic
            # ---- sensors -------------------------------------------------------------------
            ni = par[k, P.N_I]
            lsb_i = par[k, P.LSB_I]
            ia_m = _quant(ia + par[k, P.OFF_IA] + ni * _noise(rng, k), lsb_i)
            ib_m = _quant(ib + par[k, P.OFF_IB] + ni * _noise(rng, k), lsb_i)
            ic_m = _quant(ic + par[k, P.OFF_IC] + ni * _noise(rng, k), lsb_i)
            th_m = _quant(th + par[k, P.N_TH] * _noise(rng, k), par[k, P.LSB_TH])
            # measured electrical angle by a first-order rotation of the true one
            dth = pp * (th_m - th)
            cm = c - sn * dth
            sm = sn + c * dth
            cbm = -0.5 * cm + SQRT3_2 * sm
            sbm = -0.5 * sm - SQRT3_2 * cm
            ccm = -0.5 * cm - SQRT3_2 * sm
            scm = -0.5 * sm + SQRT3_2 * cm
            id_m = (2.0 / 3.0) * (ia_m * cm + ib_m * cbm + ic_m * ccm)
            iq_m = -(2.0 / 3.0) * (ia_m * sm + ib_m * sbm + ic_m * scm)
            if sub == 0:
                nv = par[k, P.N_V]
                lsb_v = par[k, P.LSB_V]
                out[j, k, 0] = ia_m
                out[j, k, 1] = ib_m
                out[j, k, 2] = ic_m
                out[j, k, 3] = _quant(ua + nv * _noise(rng, k), lsb_v)
                out[j, k, 4] = _quant(ub + nv * _noise(rng, k), lsb_v)
                out[j, k, 5] = _quant(uc + nv * _noise(rng, k), lsb_v)
                out[j, k, 6] = th_m
            # ---- speed loop (4 kHz); the position loop ran before the EMA loop ---------------
            if step % SPEED_DIV == 0:
                wraw = (th_m - st[k, _THPREV]) / dt_w
                st[k, _THPREV] = th_m
                st[k, _WF] += a_wf * (wraw - st[k, _WF])
                ew = st[k, _WREF] - st[k, _WF]
                imax = par[k, P.IMAX]
                iw = st[k, _IW] + dt_w * (par[k, P.KI_W] * ew - st[k, _IW] / par[k, P.LEAK_W])
                iw = min(max(iw, -imax), imax)
                st[k, _IW] = iw
                st[k, _IQREF] = min(max(par[k, P.KP_W] * ew + iw, -imax), imax)
            if sub == 0:  # LVDT sampled at the recording instant (the loop samples at 1 kHz)
                out[j, k, 7] = _quant(st[k, _XROD] + par[k, P.OFF_X]
                                      + par[k, P.N_X] * _noise(rng, k), par[k, P.LSB_X])
            # ---- current loop (12 kHz) -> duties for the next step ---------------------------
            kp = par[k, P.KP_I]
            ki = par[k, P.KI_I]
            lh = par[k, P.LHAT]
            weh = pp * st[k, _WF]
            ed_c = -id_m
            eq_c = st[k, _IQREF] - iq_m
            udr = kp * ed_c + st[k, _ICD] - weh * lh * iq_m
            uqr = kp * eq_c + st[k, _ICQ] + weh * (lh * id_m + par[k, P.PSIHAT])
            umax = 0.95 * udc / math.sqrt(3.0)
            umag = math.sqrt(udr * udr + uqr * uqr)
            if umag > umax:
                udr *= umax / umag
                uqr *= umax / umag
            else:
                st[k, _ICD] += ki * ed_c * dt
                st[k, _ICQ] += ki * eq_c * dt
            uar = udr * cm - uqr * sm
            ubr = udr * cbm - uqr * sbm
            ucr = -uar - ubr
            u0 = -0.5 * (max(uar, max(ubr, ucr)) + min(uar, min(ubr, ucr)))
            st[k, _DA] = min(max(0.5 + (uar + u0) / udc, 0.0), 1.0)
            st[k, _DB] = min(max(0.5 + (ubr + u0) / udc, 0.0), 1.0)
            st[k, _DC] = min(max(0.5 + (ucr + u0) / udc, 0.0), 1.0)
            # ---- electrical update (exact for frozen speed) ----------------------------------
            id_n, iq_n = _pmsm_currents(id_, iq, ud, uq, we, rt, ld, lq, psi, dpsi_dt,
                                        ad[k], aq[k])
            id_mid = 0.5 * (id_ + id_n)
            iq_mid = 0.5 * (iq + iq_n)
            te = _pmsm_torque(id_mid, iq_mid, pp, ld, lq, psi)
            # ---- link, screw friction and motor shaft (Karnopp) ------------------------------
            s_idx = int(par[k, P.SURF])
            rr = par[k, P.R_SCREW]
            arm = par[k, P.ARM]
            xnut = rr * th
            xatt = arm * delta[s_idx]
            vnut = rr * w
            vatt = arm * ddelta[s_idx]
            bl_s = par[k, P.BL_SCREW]
            bl = bl_s + par[k, P.BL_ROD]
            dx = xnut - xatt
            f, fs = _link_force(dx, vnut - vatt, 0.5 * bl, par[k, P.K_EQ], par[k, P.C_EQ])
            # rod (LVDT) position: behind the nut by the screw's share of compliance and play
            if fs > 0.0:
                xrod = xnut - fs / par[k, P.K_SCREW] - 0.5 * bl_s
            elif fs < 0.0:
                xrod = xnut - fs / par[k, P.K_SCREW] + 0.5 * bl_s
            else:
                xrod = xnut - (bl_s / bl) * dx if bl > 0.0 else xnut
            st[k, _XROD] = xrod
            torque_surf[s_idx] += arm * f
            tl = rr * f
            jm = par[k, P.J]
            eta_d = par[k, P.ETA_D]
            eta_b = par[k, P.ETA_B]
            net = te - tl
            tf = 0.0
            stuck = False
            if w == 0.0:
                direction = 1.0 if net > 0.0 else -1.0
                tfs = _screw_friction(tl, direction, par[k, P.TCS], eta_d, eta_b)
                if abs(net) <= tfs:
                    w_n = 0.0
                    stuck = True
                else:
                    tf = _screw_friction(tl, direction, par[k, P.TC], eta_d, eta_b)
                    w_n = w + dt / jm * (net - direction * tf)
            else:
                direction = 1.0 if w > 0.0 else -1.0
                tf = _screw_friction(tl, direction, par[k, P.TC], eta_d, eta_b)
                w_n = w + dt / jm * (net - direction * tf)
                if w_n * w < 0.0 or abs(w_n) < 1e-9:
                    w_n = 0.0
            st[k, _W] = w_n
            st[k, _TH] = th + dt * w_n
            st[k, _ID] = id_n
            st[k, _IQ] = iq_n
            i2 = id_mid * id_mid + iq_mid * iq_mid
            p_cu = 1.5 * rt * i2
            st[k, _PLOSS] += 1.5 * rs * i2 + p_fault
            # ---- accumulators ----------------------------------------------------------------
            wm = 0.5 * (w + w_n)
            acc[k, A.E_IN] += dt * (1.5 * (ud * id_mid + uq * iq_mid))
            acc[k, A.E_CU] += dt * p_cu
            acc[k, A.E_FRIC] += dt * tf * abs(wm)
            acc[k, A.E_LINK] += dt * tl * wm
            acc[k, A.E_FAULT] += dt * p_fault
            acc[k, A.WORK_SCREW] += dt * abs(f) * abs(rr * wm)
            acc[k, A.TRAVEL] += dt * abs(rr * wm)
            acc[k, A.WORK_ROD] += dt * abs(f) * abs(vatt)
            if stuck:
                acc[k, A.STILL_S] += dt
            if sub == 0:
                acc[k, A.TW_SUM] += st[k, _TW]
                acc[k, A.TW_MAX] = max(acc[k, A.TW_MAX], st[k, _TW])
                acc[k, A.F2_SUM] += f * f
                acc[k, A.I2_SUM] += id_ * id_ + iq * iq
                acc[k, A.N] += 1.0
                dbg[j, k, D.ID] = id_mid
                dbg[j, k, D.IQ] = iq_mid
                dbg[j, k, D.W] = w
                dbg[j, k, D.TW] = st[k, _TW]
                dbg[j, k, D.F] = f
                dbg[j, k, D.XROD] = xrod
                dbg[j, k, D.TE] = te
                dbg[j, k, D.IQREF] = st[k, _IQREF]

        # ---- surfaces ------------------------------------------------------------------------
        for s in range(n_surf):
            fa = fext[j, s] + frac * (fext[jn, s] - fext[j, s])
            m_aero = spar[s, S.N_ACT] * fa * arm_surf[s]
            m_net = m_aero + torque_surf[s] - spar[s, S.C_H] * ddelta[s]
            dd = ddelta[s] + dt * m_net / spar[s, S.J]
            ddelta[s] = dd
            delta[s] += dt * dd
            if sub == 0:
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
