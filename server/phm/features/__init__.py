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
One module per layer and per family of features; every public name is re-exported here.

* :mod:`.config` (:data:`FEATURE_VERSION`, :class:`MotorConstants`, :class:`FeatureConfig`) and
  :mod:`.results` (feature and condition names, :class:`FeatureTrack`,
  :class:`FeatureSummary`, :class:`FlightFeatures`);
* :mod:`.numerics`: the building blocks (block means, the exponential filter and
  :func:`filter_alpha`, a track from filtered accumulators, least squares);
* :mod:`.steps`: the shared preparation, :func:`actuator_steps` (800 Hz -> 80 Hz step
  quantities, :class:`ActuatorSteps`) and :func:`validity_windows`
  (:class:`ValidityWindows`); :mod:`.conditions`: temperature and operating conditions
  (:func:`winding_resistance`, :func:`winding_temperature`, :func:`operating_conditions`);
* one module per family of features, each function taking the 80 Hz arrays its formula needs
  so it can be called on its own: :mod:`.electrical` (:func:`leakage_conductance` ``F_TTS``,
  :func:`flux_deficit` ``F_DMD`` with :func:`estimated_flux`, :func:`flux_modulation`
  ``F_SE``, :func:`voltage_imbalance` ``F_BDO``), :mod:`.friction` (:func:`friction_ratio`
  ``F_MTEL``, :func:`drag_weight`), :mod:`.screw` (:func:`screw_gap` ``F_MTWEAR``),
  :mod:`.rod_end` (:func:`rewear_feature`, :func:`standby_play_feature` ``F_REWEAR``);
* :mod:`.extraction`: :func:`actuator_features` composes the preparation and the features of
  one actuator, :func:`flight_features` those of a flight's three drives by their roles.

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

from server.vocabulary import ACTUATOR_FEATURES, POSITIONS, SIGNALS, WINGLET_PAIR

from .conditions import operating_conditions, winding_resistance, winding_temperature
from .config import FEATURE_VERSION, FeatureConfig, MotorConstants
from .electrical import (
    estimated_flux,
    flux_deficit,
    flux_modulation,
    leakage_conductance,
    voltage_imbalance,
)
from .extraction import actuator_features, flight_features, standby_drive
from .friction import drag_weight, friction_ratio
from .numerics import block_mean, exp_filter, filter_alpha
from .results import (
    AIRCRAFT_FEATURES,
    CONDITION_NAMES,
    FEATURE_SENSORS,
    FeatureSummary,
    FeatureTrack,
    FlightFeatures,
)
from .rod_end import rewear_feature, standby_play_feature
from .screw import screw_gap
from .steps import ActuatorSteps, ValidityWindows, actuator_steps, validity_windows

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
    "drag_weight",
    "screw_gap",
    "actuator_features",
    "rewear_feature",
    "standby_play_feature",
    "operating_conditions",
    "standby_drive",
    "flight_features",
]
