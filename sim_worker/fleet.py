"""Fleet: bases with their climate, control surfaces, and aircraft with production scatter.

An :class:`Aircraft` holds, per position ``WL1``, ``WL2`` (winglet tab, shared surface) and ``WT``
(wingtip), the actuator's plant parameters drawn around the catalogue values within production
tolerances (1 sigma, truncated at 3 sigma), its sensor offsets and serial number. Everything is
drawn from a ``numpy.random.Generator`` seeded by the aircraft seed.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass, field, replace
from enum import StrEnum
from importlib import resources
from typing import Any

import numpy as np

from server.vocabulary import BASES as BASE_NAMES
from server.vocabulary import POSITIONS, WINGLET_PAIR, is_winglet

from .params import EmaParams, SurfaceParams

__all__ = [
    "POSITIONS",
    "BASES",
    "CLIMATES",
    "WINGLET",
    "WINGTIP",
    "SURFACE_OF",
    "WingletMode",
    "DEFAULT_WINGLET_MODE",
    "active_channels",
    "Aircraft",
    "build_aircraft",
    "monthly_climate",
    "draw_ground_temperature",
    "annual_mean_temperature",
    "seasonal_offset_c",
]

BASES: dict[str, str] = dict(zip(BASE_NAMES, ("temperate", "cold", "hot"), strict=True))
CLIMATES: dict[str, str] = {v: k for k, v in BASES.items()}
#: the ten aircraft's home bases of a campaign or a simulated fleet (paper section 4.1): four
#: temperate, three cold, three hot
FLEET_BASES: tuple[str, ...] = ("Turin",) * 4 + ("Vancouver",) * 3 + ("Abu Dhabi",) * 3
_CLIMATE_FILES = {"Turin": "climate_turin.csv", "Vancouver": "climate_vancouver.csv",
                  "Abu Dhabi": "climate_abu_dhabi.csv"}

#: the winglet tab's hinge load is two shares of 40 kN/m and 250 N at the rod (about 2.7 kN at
#: full deflection and cruise): one drive holds it alone with its 3-sigma warp (4.7 kN, against
#: the drive's 7 kN at its 17 A limit), as an active-standby pair must
WINGLET = SurfaceParams(name="WL", j_kgm2=0.08, arm_m=0.045, hinge_damping_nms=15.0,
                        n_actuators=2, aero_stiffness_n_per_m=4.0e4, aero_bias_n=250.0,
                        nominal_load_n=1000.0)
WINGTIP = SurfaceParams(name="WT", j_kgm2=0.04, arm_m=0.040, hinge_damping_nms=8.0,
                        n_actuators=1, aero_stiffness_n_per_m=6.0e4, aero_bias_n=300.0,
                        nominal_load_n=1500.0)
#: surface index of each position: 0 the winglet tab (the winglet pair), 1 the wingtip
SURFACE_OF: dict[str, int] = {pos: 0 if is_winglet(pos) else 1 for pos in POSITIONS}


class WingletMode(StrEnum):
    """How the winglet pair moves its tab."""

    #: one channel drives, the other is in standby, attached and damping (the iron bird, paper
    #: section 3.3.3 and Figure 9)
    ACTIVE_STANDBY = "active-standby"
    #: both channels drive on their consolidated LVDT
    ACTIVE_ACTIVE = "active-active"


#: the iron bird's tab (paper Figure 9): campaigns, the test station and every simulated flight
#: fly it unless told otherwise
DEFAULT_WINGLET_MODE = WingletMode.ACTIVE_STANDBY


def active_channels(mode: WingletMode, flight_index: int) -> tuple[str, ...]:
    """Positions whose drives are active on flight ``flight_index`` of an aircraft.

    Under active-standby the winglet's active channel alternates by flight, WL1 on even
    flights: redundancy management exercises both channels, so a fault dormant in a standby's
    inverter or loops cannot hide for more than one flight, and every motor fault of either
    drive shows through a switching inverter on every second flight.
    """
    if WingletMode(mode) is WingletMode.ACTIVE_ACTIVE:
        return POSITIONS
    idle = WINGLET_PAIR[1 - flight_index % 2]
    return tuple(p for p in POSITIONS if p != idle)

# production tolerances, 1 sigma relative (or absolute where stated) [est]
_TOL = {
    "r_s": 0.02, "l": 0.03, "psi": 0.015, "j": 0.03, "eta": 0.01, "drag": 0.10, "k": 0.08,
    "r_th": 0.05, "c_th": 0.05,
}


@dataclass(frozen=True)
class Aircraft:
    """One aircraft of the fleet; ``ema`` and ``offsets`` are keyed by position."""

    tail: str
    base: str
    seed: int
    serials: dict[str, str]
    ema: dict[str, EmaParams]
    offsets: dict[str, tuple[float, float, float, float]]  # ia, ib, ic [A], lvdt [m]
    nominal: EmaParams = field(default_factory=EmaParams)

    @property
    def climate(self) -> str:
        return BASES[self.base]

    def with_lvdt_offset(self, position: str, metres: float) -> Aircraft:
        """This aircraft with the LVDT of ``position`` off by ``metres`` (its rigging offset
        replaced; the current offsets kept): a drifting sensor, flown as the kernel reads it."""
        ia, ib, ic, _ = self.offsets[position]
        return replace(self, offsets={**self.offsets, position: (ia, ib, ic, float(metres))})

    def params_summary(self) -> dict[str, Any]:
        """Per-position parameters that differ between aircraft (for the manifest)."""
        out: dict[str, Any] = {}
        for pos, p in self.ema.items():
            out[pos] = {
                "r_s_ohm": round(p.motor.r_s_ohm, 5), "l_h": round(p.motor.l_q_h, 7),
                "psi_pm_wb": round(p.motor.psi_pm_wb, 6), "j_kgm2": round(p.motor.j_kgm2, 8),
                "eta_direct": round(p.screw.eta_direct, 5),
                "coulomb_torque_nm": round(p.screw.coulomb_torque_nm, 5),
                "k_screw_n_per_m": round(p.screw.k_screw_n_per_m, 1),
                "k_rod_end_n_per_m": round(p.screw.k_rod_end_n_per_m, 1),
                "backlash_screw_m": round(p.screw.backlash_screw_m, 8),
                "backlash_rod_end_m": round(p.screw.backlash_rod_end_m, 8),
                "r_th_k_per_w": round(p.thermal.r_th_k_per_w, 4),
            }
        return out


def _scatter(rng: np.random.Generator, rel: float) -> float:
    return float(1.0 + rel * np.clip(rng.standard_normal(), -3.0, 3.0))


def build_aircraft(tail: str, base: str, seed: int) -> Aircraft:
    """Draw one aircraft's three actuators around the catalogue values."""
    if base not in BASES:
        raise ValueError(f"unknown base {base!r}; expected one of {sorted(BASES)}")
    rng = np.random.default_rng(seed)
    nominal = EmaParams()
    ema: dict[str, EmaParams] = {}
    offsets: dict[str, tuple[float, float, float, float]] = {}
    serials: dict[str, str] = {}
    for pos in POSITIONS:
        m, s, th, sen = nominal.motor, nominal.screw, nominal.thermal, nominal.sensors
        l_scale = _scatter(rng, _TOL["l"])
        motor = replace(m, r_s_ohm=m.r_s_ohm * _scatter(rng, _TOL["r_s"]),
                        l_d_h=m.l_d_h * l_scale, l_q_h=m.l_q_h * l_scale,
                        psi_pm_wb=m.psi_pm_wb * _scatter(rng, _TOL["psi"]),
                        j_kgm2=m.j_kgm2 * _scatter(rng, _TOL["j"]))
        screw = replace(
            s,
            eta_direct=min(0.95, s.eta_direct * _scatter(rng, _TOL["eta"])),
            coulomb_torque_nm=s.coulomb_torque_nm * _scatter(rng, _TOL["drag"]),
            k_screw_n_per_m=s.k_screw_n_per_m * _scatter(rng, _TOL["k"]),
            k_rod_end_n_per_m=s.k_rod_end_n_per_m * _scatter(rng, _TOL["k"]),
            backlash_screw_m=float(rng.uniform(2e-6, 20e-6)),
            backlash_rod_end_m=float(rng.uniform(10e-6, 25e-6)),
        )
        thermal = replace(th, r_th_k_per_w=th.r_th_k_per_w * _scatter(rng, _TOL["r_th"]),
                          c_th_j_per_k=th.c_th_j_per_k * _scatter(rng, _TOL["c_th"]))
        ema[pos] = replace(nominal, motor=motor, screw=screw, thermal=thermal)
        off = rng.normal(0.0, sen.current_offset_a, 3)
        offsets[pos] = (float(off[0]), float(off[1]), float(off[2]),
                        float(rng.normal(0.0, sen.lvdt_offset_m)))
        serials[pos] = f"EMA-{tail}-{pos}-{int(rng.integers(10000, 99999))}"
    return Aircraft(tail=tail, base=base, seed=int(seed), serials=serials, ema=ema,
                    offsets=offsets, nominal=nominal)


def monthly_climate(base: str) -> tuple[np.ndarray, np.ndarray]:
    """(mean, std) of the daily mean temperature per month [degC], index 0 = January."""
    text = resources.files("sim_worker").joinpath("data", _CLIMATE_FILES[base]).read_text()
    rows = list(csv.DictReader(text.splitlines()))
    mean = np.array([float(r["mean_c"]) for r in rows])
    std = np.array([float(r["std_c"]) for r in rows])
    return mean, std


def draw_ground_temperature(base: str, month: int, rng: np.random.Generator) -> float:
    """Ground temperature of one flight [degC] for calendar ``month`` (1-12)."""
    mean, std = monthly_climate(base)
    return float(mean[month - 1] + std[month - 1] * rng.standard_normal())


def annual_mean_temperature(base: str) -> float:
    mean, _ = monthly_climate(base)
    return float(np.mean(mean))


def seasonal_offset_c(base: str, day_of_year: float | np.ndarray) -> np.ndarray:
    """The base's expected daily mean temperature on ``day_of_year`` (0 = 1 January, any
    real, wrapping over the year) minus its annual mean [K]: the monthly means placed at
    mid-month and interpolated linearly around the year, so a planned season has no steps."""
    mean, _ = monthly_climate(base)
    mid_month = (np.arange(12) + 0.5) * (365.25 / 12)
    return np.interp(np.asarray(day_of_year, dtype=float) % 365.25, mid_month,
                     mean - mean.mean(), period=365.25)


def reflected_mass_kg(p: EmaParams) -> float:
    return p.motor.j_kgm2 / p.screw.r_m_per_rad**2

