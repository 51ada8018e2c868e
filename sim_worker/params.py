"""Plant parameters, controller tuning and sensor models of one EMA and its control surface.

Conventions: SI units throughout; motor currents and voltages are peak values in the
amplitude-invariant d-q frame (``i_a = i_d cos(th_e) - i_q sin(th_e)``); the rod position ``x`` is
positive in extension, zero at neutral; an aerodynamic force is positive along ``+x``.

Each dataclass is frozen; :func:`pack_ema` and :func:`pack_surface` flatten them (plus the fault
state) into the float64 rows that the numba kernel (:mod:`sim_worker.kernel`) reads by index.
Controller gains are derived in one place (:func:`derive_gains`) from bandwidths and from the
controller's own *nominal* parameter estimate, so that production scatter of the plant is a normal
model mismatch, as on a real drive.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from enum import IntEnum

import numpy as np

__all__ = [
    "MotorParams",
    "InverterParams",
    "ScrewParams",
    "ThermalParams",
    "SensorParams",
    "ControlTuning",
    "EmaParams",
    "SurfaceParams",
    "STEP_HZ",
    "OUT_HZ",
    "screw_efficiencies",
    "friction_angle_for_efficiency",
    "derive_gains",
    "pack_ema",
    "pack_surface",
    "P",
    "N_PAR",
    "S",
    "N_SURF_PAR",
]

STEP_HZ = 12_000.0  # Hz, fixed integration step (the paper's RT limit)
OUT_HZ = 800.0  # Hz, download sample rate
SPEED_DIV = 3  # speed loop every 3 steps (4 kHz)
POS_DIV = 12  # position loop every 12 steps (1 kHz)


@dataclass(frozen=True)
class MotorParams:
    """PMSM, Wittenstein premo SP "2D" class (datasheet: R_tt 3.72 Ohm, L_tt 7.43 mH, K_t 0.52
    N m/A_rms, I_max 12 A_rms, 4 pole pairs), in amplitude-invariant d-q values."""

    r_s_ohm: float = 1.86  # Ohm, phase resistance at t_ref_c
    l_d_h: float = 3.72e-3  # H, d-axis inductance
    l_q_h: float = 3.72e-3  # H, q-axis inductance
    psi_pm_wb: float = 0.061  # Wb (peak), PM flux linkage at t_ref_c
    pole_pairs: int = 4  # -
    j_kgm2: float = 1.0e-4  # kg m^2, rotor + screw shaft inertia
    t_ref_c: float = 20.0  # degC, reference temperature of r_s and psi_pm
    alpha_cu_per_k: float = 0.00393  # 1/K, copper resistance coefficient
    alpha_br_per_k: float = -0.0011  # 1/K, NdFeB remanence coefficient
    i_max_a: float = 17.0  # A peak (12 A rms), current limit of the drive


@dataclass(frozen=True)
class InverterParams:
    """Averaged three-leg MOSFET inverter on the HVDC link."""

    u_dc_v: float = 270.0  # V, DC link
    r_on_ohm: float = 0.02  # Ohm, conduction resistance per leg at 25 degC [est]
    alpha_on_per_k: float = 0.005  # 1/K, MOSFET on-resistance coefficient [est]
    #: Ohm per phase, the standby channel's damping star (a normally-closed contactor closes the
    #: windings on it whenever the channel is not active or not powered, so the back-driven
    #: magnet motor damps the surface against flutter, paper section 3.2). 10 Ohm gives 12 kN s/m
    #: at the rod at low speed (1.5 p^2 psi^2 / (R_s + R_d) / r^2), 1.6 times the winglet tab's
    #: hinge damping, and leaves the active drive about 1 kN of force margin on the reference
    #: cycle's fastest loaded move (50 mm/s at 6.3 kN of hinge load) [est]
    damping_resistance_ohm: float = 10.0


@dataclass(frozen=True)
class ScrewParams:
    """Ball screw 16 mm x 5 mm lead (the paper's Fig. 7), rod end and their backlash/compliance
    (stiffness, within 5e7-2e8 N/m, and free play when new are engineering estimates)."""

    lead_m: float = 5.0e-3  # m per rev
    nominal_diameter_m: float = 16.0e-3  # m
    eta_direct: float = 0.90  # -, direct-drive efficiency when new
    coulomb_torque_nm: float = 0.04  # N m, load-independent drag (seals, bearings)
    static_factor: float = 1.3  # -, breakaway / sliding friction ratio
    k_screw_n_per_m: float = 1.0e8  # N/m, screw + nut + bearing stiffness
    k_rod_end_n_per_m: float = 1.0e8  # N/m, rod-end and attachment stiffness
    damping_ratio: float = 0.1  # -, structural damping of the link (hysteretic -> viscous)
    backlash_screw_m: float = 10e-6  # m, total free play of the screw when new
    backlash_rod_end_m: float = 15e-6  # m, total free play of the rod end when new
    stroke_half_m: float = 0.030  # m

    @property
    def r_m_per_rad(self) -> float:
        """Transmission ratio lead / 2 pi [m/rad]."""
        return self.lead_m / (2.0 * math.pi)

    @property
    def lead_angle_rad(self) -> float:
        """Helix angle of the screw [rad]."""
        return math.atan(self.lead_m / (math.pi * self.nominal_diameter_m))

    def efficiencies(self, efficiency_loss: float = 0.0) -> tuple[float, float]:
        """(direct, back-driving) efficiency with the direct one lowered by
        ``efficiency_loss`` (aged grease), through the same friction angle."""
        rho = friction_angle_for_efficiency(self.lead_angle_rad,
                                            self.eta_direct - efficiency_loss)
        return screw_efficiencies(self.lead_angle_rad, rho)


@dataclass(frozen=True)
class ThermalParams:
    """Single-body thermal model of the motor (datasheet R_th and tau_th)."""

    r_th_k_per_w: float = 0.81  # K/W, winding to ambient
    c_th_j_per_k: float = 1290.0  # J/K, tau_th 17.4 min / R_th


@dataclass(frozen=True)
class SensorParams:
    """Noise (rms), offset scatter (1 sigma, drawn per actuator) and quantisation steps."""

    current_noise_a: float = 0.04  # A rms
    current_offset_a: float = 0.03  # A, 1 sigma per phase
    current_lsb_a: float = 2.0**-5  # A, 12-bit over +-64 A
    voltage_noise_v: float = 0.8  # V rms
    voltage_lsb_v: float = 2.0**-3  # V, 13-bit over +-512 V
    resolver_noise_rad: float = 2.0e-4  # rad rms
    resolver_lsb_rad: float = 2.0 * math.pi / 65536  # rad, 16 bit per turn
    lvdt_noise_m: float = 2.0e-6  # m rms
    lvdt_offset_m: float = 5.0e-6  # m, 1 sigma after rigging
    lvdt_lsb_m: float = 2.0**-19  # m (1.9 um), 16-bit over +-62 mm
    #: a failed sensor's readings held in [low, high] (test-station injections: clipped at a
    #: level is (-level, level), stuck at a value is (value, value)); None: a sound sensor
    current_clamp_a: tuple[float, float] | None = None
    voltage_clamp_v: tuple[float, float] | None = None
    resolver_clamp_rad: tuple[float, float] | None = None
    lvdt_clamp_m: tuple[float, float] | None = None


@dataclass(frozen=True)
class ControlTuning:
    """Bandwidths of the three nested loops, within the usual ranges: current 500-1000 Hz, speed
    30-80 Hz, position 5-15 Hz."""

    current_bw_hz: float = 800.0  # Hz, PI in d-q, Kp = a L, Ki = a R
    speed_bw_hz: float = 50.0  # Hz, speed PI
    speed_integral_ratio: float = 5.0  # -, speed PI zero at bw / ratio
    speed_leak_s: float = 1.0e6  # s, speed-integrator leak (1e6: a pure integrator)
    position_bw_hz: float = 8.0  # Hz, position P on the LVDT
    max_motor_speed_rad_s: float = 2.0 * math.pi * 80.0  # rad/s, speed-reference clamp


@dataclass(frozen=True)
class EmaParams:
    """One electromechanical actuator: plant, sensors and controller tuning."""

    motor: MotorParams = field(default_factory=MotorParams)
    inverter: InverterParams = field(default_factory=InverterParams)
    screw: ScrewParams = field(default_factory=ScrewParams)
    thermal: ThermalParams = field(default_factory=ThermalParams)
    sensors: SensorParams = field(default_factory=SensorParams)
    tuning: ControlTuning = field(default_factory=ControlTuning)

    def with_(self, **parts: object) -> EmaParams:
        # replace() checks every field against **parts' one type: the caller names the parts
        return replace(self, **parts)  # type: ignore[arg-type]


@dataclass(frozen=True)
class SurfaceParams:
    """A control surface with its horn arm; load law for the scenario."""

    name: str
    j_kgm2: float  # kg m^2, surface inertia about the hinge
    arm_m: float  # m, horn arm (rod travel per radian)
    hinge_damping_nms: float  # N m s/rad, aerodynamic + hinge damping
    n_actuators: int  # -, drives on the surface
    aero_stiffness_n_per_m: float  # N/m per actuator at cruise dynamic pressure (rod coordinates)
    aero_bias_n: float  # N per actuator at cruise, hinge load at zero deflection
    nominal_load_n: float  # N per actuator, reference for the scenario offsets


def screw_efficiencies(lead_angle_rad: float, friction_angle_rad: float) -> tuple[float, float]:
    """Direct and back-driving efficiency of a screw: tan(b)/tan(b+rho), tan(b-rho)/tan(b)."""
    b, rho = lead_angle_rad, friction_angle_rad
    return math.tan(b) / math.tan(b + rho), max(math.tan(b - rho), 0.0) / math.tan(b)


def friction_angle_for_efficiency(lead_angle_rad: float, eta_direct: float) -> float:
    """Friction angle rho [rad] giving the direct efficiency ``eta_direct``."""
    return math.atan(math.tan(lead_angle_rad) / eta_direct) - lead_angle_rad


@dataclass(frozen=True)
class Gains:
    kp_i: float  # V/A
    ki_i: float  # V/(A s)
    kp_w: float  # A/(rad/s)
    ki_w: float  # A/rad
    kp_x: float  # (rad/s)/m, motor speed reference per metre of rod error


def derive_gains(nominal: EmaParams) -> Gains:
    """Loop gains from bandwidths and the controller's *nominal* parameter estimate."""
    m, t, s = nominal.motor, nominal.tuning, nominal.screw
    a_i = 2.0 * math.pi * t.current_bw_hz
    kt = 1.5 * m.pole_pairs * m.psi_pm_wb  # N m / A peak
    a_w = 2.0 * math.pi * t.speed_bw_hz
    kp_w = a_w * m.j_kgm2 / kt
    ki_w = kp_w * a_w / t.speed_integral_ratio
    a_x = 2.0 * math.pi * t.position_bw_hz
    return Gains(kp_i=a_i * m.l_q_h, ki_i=a_i * m.r_s_ohm, kp_w=kp_w, ki_w=ki_w,
                 kp_x=a_x / s.r_m_per_rad)


# ---- parameter row layout read by the kernel ------------------------------------------------


class P(IntEnum):
    """Indices into one EMA's parameter row (float64)."""

    R0 = 0
    LD = 1
    LQ = 2
    PSI0 = 3
    PP = 4
    J = 5
    TREF = 6
    ALPHA_CU = 7
    ALPHA_BR = 8
    IMAX = 9
    UDC = 10
    RON = 11
    ALPHA_ON = 12
    R_SCREW = 13
    ETA_D = 14
    ETA_B = 15
    TC = 16
    TCS = 17
    K_EQ = 18
    C_EQ = 19
    K_SCREW = 20
    BL_SCREW = 21
    BL_ROD = 22
    ARM = 23
    SURF = 24
    RTH = 25
    CTH = 26
    KP_I = 27
    KI_I = 28
    KP_W = 29
    KI_W = 30
    LEAK_W = 31
    KP_X = 32
    WMAX = 33
    LHAT = 34
    PSIHAT = 35
    RHAT = 36
    N_I = 37
    OFF_IA = 38
    OFF_IB = 39
    OFF_IC = 40
    LSB_I = 41
    N_V = 42
    LSB_V = 43
    N_TH = 44
    LSB_TH = 45
    N_X = 46
    OFF_X = 47
    LSB_X = 48
    TTS_SIGMA = 49  # fraction of phase-a turns shorted
    TTS_RF = 50  # Ohm, resistance of the short
    TTS_G = 51  # S, leakage conductance winding -> frame
    DMD_H = 52  # -, irreversible flux loss fraction
    SE_EPS = 53  # -, relative flux modulation by static eccentricity
    SE_PHI = 54  # rad, angle of the narrowest gap
    BDO_LEG = 55  # -1 none, 0/1/2 phase a/b/c
    BDO_UPPER = 56  # 1 upper switch open, 0 lower
    T0_W = 57  # degC, initial winding temperature
    STANDBY = 58  # 1 standby (inverter off, windings on the damping star), 0 active
    R_DAMP = 59  # Ohm per phase, the damping star of a standby channel
    # a failed sensor's output clamp (SensorParams.*_clamp): on (1) or off (0), low, high
    CL_I = 60
    LO_I = 61
    HI_I = 62
    CL_V = 63
    LO_V = 64
    HI_V = 65
    CL_TH = 66
    LO_TH = 67
    HI_TH = 68
    CL_X = 69
    LO_X = 70
    HI_X = 71


N_PAR = 72


class S(IntEnum):
    """Indices into one surface's parameter row."""

    J = 0
    C_H = 1
    N_ACT = 2


N_SURF_PAR = 3


def pack_ema(
    p: EmaParams,
    nominal: EmaParams,
    *,
    surface: int,
    arm_m: float,
    offsets: tuple[float, float, float, float],
    faults: dict[str, float],
    t0_winding_c: float,
    standby: bool = False,
) -> np.ndarray:
    """One kernel parameter row. ``faults`` holds already-applied fault entries (see faults.py);
    ``standby``: the channel does not drive (active-standby pair, see kernel.py)."""
    m, inv, s, th, sen = p.motor, p.inverter, p.screw, p.thermal, p.sensors
    g = derive_gains(nominal)
    row = np.zeros(N_PAR)
    eta_d, eta_b = s.efficiencies(faults.get("mtel_deta", 0.0))
    k_eq = 1.0 / (1.0 / s.k_screw_n_per_m + 1.0 / s.k_rod_end_n_per_m)
    # link damping from the damping ratio of the reflected-motor / link mode
    m_ref = m.j_kgm2 / s.r_m_per_rad**2
    row[P.R0], row[P.LD], row[P.LQ], row[P.PSI0] = m.r_s_ohm, m.l_d_h, m.l_q_h, m.psi_pm_wb
    row[P.PP], row[P.J], row[P.TREF] = m.pole_pairs, m.j_kgm2, m.t_ref_c
    row[P.ALPHA_CU], row[P.ALPHA_BR], row[P.IMAX] = m.alpha_cu_per_k, m.alpha_br_per_k, m.i_max_a
    row[P.UDC], row[P.RON], row[P.ALPHA_ON] = inv.u_dc_v, inv.r_on_ohm, inv.alpha_on_per_k
    row[P.R_SCREW], row[P.ETA_D], row[P.ETA_B] = s.r_m_per_rad, eta_d, eta_b
    row[P.TC] = s.coulomb_torque_nm * (1.0 + faults.get("mtel_drag", 0.0))
    row[P.TCS] = row[P.TC] * s.static_factor
    row[P.K_EQ], row[P.C_EQ] = k_eq, 2.0 * s.damping_ratio * math.sqrt(k_eq * m_ref)
    row[P.K_SCREW] = s.k_screw_n_per_m
    row[P.BL_SCREW] = s.backlash_screw_m + faults.get("screw_backlash_m", 0.0)
    row[P.BL_ROD] = s.backlash_rod_end_m + faults.get("rod_end_backlash_m", 0.0)
    row[P.ARM], row[P.SURF] = arm_m, surface
    row[P.RTH], row[P.CTH] = th.r_th_k_per_w, th.c_th_j_per_k
    row[P.KP_I], row[P.KI_I], row[P.KP_W], row[P.KI_W] = g.kp_i, g.ki_i, g.kp_w, g.ki_w
    row[P.LEAK_W], row[P.KP_X] = p.tuning.speed_leak_s, g.kp_x
    row[P.WMAX] = p.tuning.max_motor_speed_rad_s
    row[P.LHAT], row[P.PSIHAT], row[P.RHAT] = (nominal.motor.l_q_h, nominal.motor.psi_pm_wb,
                                               nominal.motor.r_s_ohm)
    row[P.N_I], row[P.LSB_I] = sen.current_noise_a, sen.current_lsb_a
    row[P.OFF_IA], row[P.OFF_IB], row[P.OFF_IC], row[P.OFF_X] = offsets
    row[P.N_V], row[P.LSB_V] = sen.voltage_noise_v, sen.voltage_lsb_v
    row[P.N_TH], row[P.LSB_TH] = sen.resolver_noise_rad, sen.resolver_lsb_rad
    row[P.N_X], row[P.LSB_X] = sen.lvdt_noise_m, sen.lvdt_lsb_m
    row[P.TTS_SIGMA] = faults.get("tts_sigma", 0.0)
    row[P.TTS_RF] = faults.get("tts_rf_ohm", 0.1)
    row[P.TTS_G] = faults.get("tts_g_s", 0.0)
    row[P.DMD_H] = faults.get("dmd_h", 0.0)
    row[P.SE_EPS] = faults.get("se_eps", 0.0)
    row[P.SE_PHI] = faults.get("se_phi", 0.0)
    row[P.BDO_LEG] = faults.get("bdo_leg", -1.0)
    row[P.BDO_UPPER] = faults.get("bdo_upper", 1.0)
    row[P.T0_W] = t0_winding_c
    row[P.STANDBY] = 1.0 if standby else 0.0
    row[P.R_DAMP] = inv.damping_resistance_ohm
    for first, clamp in ((P.CL_I, sen.current_clamp_a), (P.CL_V, sen.voltage_clamp_v),
                         (P.CL_TH, sen.resolver_clamp_rad), (P.CL_X, sen.lvdt_clamp_m)):
        if clamp is not None:
            row[first], row[first + 1], row[first + 2] = 1.0, clamp[0], clamp[1]
    return row


def pack_surface(s: SurfaceParams) -> np.ndarray:
    row = np.zeros(N_SURF_PAR)
    row[S.J], row[S.C_H], row[S.N_ACT] = s.j_kgm2, s.hinge_damping_nms, s.n_actuators
    return row
