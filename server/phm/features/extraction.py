"""Per actuator and per flight: the shared preparation composed with one function per feature
(:func:`actuator_features`), and the 20 features of a flight with each drive's role taken
from the log (:func:`flight_features`).
"""

from __future__ import annotations

from collections.abc import Collection, Mapping

import numpy as np

from server.vocabulary import POSITIONS, REWEAR_FEATURE, SIGNALS, WINGLET_PAIR

from ..signal_quality import flight_quality
from .conditions import (
    operating_conditions,
    resistance_or_nominal,
    step_conditions,
    winding_resistance,
)
from .config import FeatureConfig, MotorConstants
from .electrical import (
    estimated_flux,
    flux_deficit,
    flux_modulation,
    leakage_conductance,
    voltage_imbalance,
)
from .friction import drag_weight, friction_ratio
from .results import AIRCRAFT_FEATURES, FeatureSummary, FeatureTrack, FlightFeatures
from .rod_end import rewear_feature, standby_play_feature
from .screw import screw_gap
from .steps import ActuatorSteps, actuator_steps, validity_windows

__all__ = ["actuator_features", "standby_drive", "flight_features"]


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
              **step_conditions(steps, aero_gradient_n_per_m, aero_bias_n, r_hat, motor),
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
    emf = steps.v_q - resistance_or_nominal(r_hat, mc) * steps.i_q  # V, q-axis back-EMF
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
        conditions[p] = {**flight_cond, **step_conditions(
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
