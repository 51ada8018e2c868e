"""The feature extraction's version, the nominal motor constants it assumes and its windows,
thresholds and filter (:class:`FeatureConfig`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

__all__ = ["FEATURE_VERSION", "MotorConstants", "FeatureConfig"]


#: bumped whenever a feature formula or validity changes (invalidates cached campaign
#: features); the history of the bumps is in docs/TUNING.md
FEATURE_VERSION = "features/10"


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
