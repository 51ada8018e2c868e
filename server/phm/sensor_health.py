"""Healthy bands of the signal-quality figures, and the sensor findings of a flight.

Time base: one assessment per flight. Input: the figures of
:func:`server.phm.signal_quality.flight_quality` (channel -> metric -> value).

Bands, learned per channel on the healthy design flights:

* ``noise``, on each sensor's floor channel (``i_sum``, ``v_sum``, ``theta``, ``x``: the
  figures that carry the sensor's own noise, not the drive's ripple), on a log scale:
  ``log(floor)`` against its healthy median ``m`` with robust spread ``s`` (1.4826 MAD),
  a finding above ``m + max(k s, log(1 + min_rise))``.
  One-sided: a quieter channel harms no feature, and a dead one is ``stuck``.
  ``k`` is set for a stated rate of spurious findings per flight (``false_finding_rate``,
  shared by Sidak's rule among every channel and metric of the aircraft), and
  ``min_rise`` (30 %) keeps a band that a handful of design flights measured too narrow from
  flagging a sensor whose floor moved by a few per cent with the season or the load.
* ``offset`` (LVDT): the rod position against the motor shaft [m], within the healthy
  ``offset_quantile`` (0.5 %) and ``1 - offset_quantile`` quantiles widened by
  ``min_offset_m`` (20 um) each side: the fleet's rigging offsets (5 um, 1 sigma) and load
  deflections spread it, with tails heavier than normal.
* ``lsb``, on every recorded channel: coarser than the design's step by more than half a step
  (another recorder or a bit lost).
* ``stuck`` and ``saturated``, on every recorded channel: a share of the flight above the
  design's largest share plus ``max_share`` (1 %).

A finding names the channel, its sensor, the metric, the measured value and its band. The
chain uses the findings to judge the features that read the channel
(:mod:`server.phm.chain.run`). Persisted as JSON (``to_dict`` / ``from_dict``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.special import ndtri

from server.vocabulary import POSITIONS, REWEAR_FEATURE, SENSOR_OF_SIGNAL, SIGNALS, WINGLET_PAIR

from .features import FEATURE_SENSORS, FlightFeatures
from .signal_quality import FLOOR_CHANNELS

__all__ = ["SENSOR_HEALTH_FORMAT", "SensorFinding", "SensorBands", "NoiseSensitivity",
           "SensorJudgement", "SensorModel", "channel_sensor",
           "fit_sensor_model"]

SENSOR_HEALTH_FORMAT = "ema-sensor-bands/1"
_METRICS = ("noise", "offset", "lsb", "stuck", "saturated")


def channel_sensor(channel: str) -> tuple[str, str]:
    """``"WT.ia"`` -> ``("WT", "current")``: the actuator and the sensor of a channel (a
    recorded one or a floor channel such as ``"WT.i_sum"``)."""
    position, signal = channel.split(".", 1)
    return position, SENSOR_OF_SIGNAL.get(signal) or FLOOR_CHANNELS[signal]


#: the floor channel of each sensor
_FLOOR_OF = {sensor: ch for ch, sensor in FLOOR_CHANNELS.items()}


@dataclass(frozen=True)
class SensorFinding:
    """A channel whose figure left its healthy band on one flight."""

    channel: str  # "<position>.<signal>"
    metric: str  # one of noise, offset, lsb, stuck, saturated
    value: float
    low: float
    high: float

    @property
    def position(self) -> str:
        return channel_sensor(self.channel)[0]

    @property
    def sensor(self) -> str:
        return channel_sensor(self.channel)[1]

    def to_dict(self) -> dict[str, Any]:
        return {"channel": self.channel, "sensor": self.sensor, "metric": self.metric,
                "value": self.value, "low": self.low, "high": self.high}


def _robust(x: np.ndarray) -> tuple[float, float]:
    med = float(np.median(x))
    return med, float(1.4826 * np.median(np.abs(x - med)))


@dataclass
class SensorBands:
    """Healthy bands of every channel's signal-quality figures (see the module docstring)."""

    false_finding_rate: float = 1e-3
    min_rise: float = 0.3
    offset_quantile: float = 0.005
    min_offset_m: float = 20e-6
    max_share: float = 0.01

    def __post_init__(self) -> None:
        self.bands_: dict[str, dict[str, tuple[float, float]]] = {}
        self.floor_medians_: dict[str, float] = {}  # healthy median noise floor per channel

    @property
    def k(self) -> float:
        """Robust scales at which a figure leaves its band."""
        tests = len(POSITIONS) * len(FLOOR_CHANNELS)  # the noise floors, one-sided
        q = 1.0 - (1.0 - self.false_finding_rate) ** (1.0 / tests)
        return float(ndtri(1.0 - q))

    def fit(self, qualities: Sequence[Mapping[str, Mapping[str, float]]]) -> SensorBands:
        """Learn the bands from the figures of healthy design flights."""
        if not qualities:
            raise ValueError("no healthy flights with signal-quality figures to learn from")
        channels = [f"{p}.{s}" for p in POSITIONS
                    for s in dict.fromkeys(SIGNALS + tuple(FLOOR_CHANNELS))]
        self.bands_, self.floor_medians_ = {}, {}
        for ch in channels:
            self.bands_[ch] = self._channel_bands(ch, [q[ch] for q in qualities if ch in q])
        return self

    def _channel_bands(self, channel: str, figs: Sequence[Mapping[str, float]]
                       ) -> dict[str, tuple[float, float]]:
        def col(metric: str) -> np.ndarray:
            v = np.array([f.get(metric, math.nan) for f in figs], dtype=np.float64)
            return v[np.isfinite(v)]

        out: dict[str, tuple[float, float]] = {}
        noise = col("noise") if channel.split(".", 1)[1] in FLOOR_CHANNELS else np.zeros(0)
        if noise.size and np.all(noise > 0):
            m, s = _robust(np.log(noise))
            # one-sided: a floor below the healthy one harms no feature (the loops' share of
            # the floor falls with light loads); a channel gone dead is "stuck"
            out["noise"] = (0.0, math.exp(m + max(self.k * s, math.log1p(self.min_rise))))
            self.floor_medians_[channel] = math.exp(m)
        offset = col("offset")
        if offset.size:
            lo, hi = np.quantile(offset, [self.offset_quantile, 1.0 - self.offset_quantile])
            out["offset"] = (float(lo) - self.min_offset_m, float(hi) + self.min_offset_m)
        lsb = col("lsb")
        if lsb.size:
            step = float(np.median(lsb))
            out["lsb"] = (0.0, 1.5 * step)
        for metric in ("stuck", "saturated"):
            share = col(metric)
            if share.size:
                out[metric] = (0.0, float(share.max()) + self.max_share)
        return out

    def _check(self) -> None:
        if not self.bands_:
            raise RuntimeError("SensorBands is not fitted")

    def assess(self, quality: Mapping[str, Mapping[str, float]]) -> list[SensorFinding]:
        """The findings of one flight: every figure outside its band (NaN figures, e.g. a
        flight without holds, are no finding)."""
        self._check()
        found = []
        for ch, bands in self.bands_.items():
            figs = quality.get(ch, {})
            for metric in _METRICS:
                if metric not in bands:
                    continue
                v = figs.get(metric, math.nan)
                lo, hi = bands[metric]
                if v is not None and math.isfinite(v) and not lo <= v <= hi:
                    found.append(SensorFinding(ch, metric, float(v), lo, hi))
        return found

    def to_dict(self) -> dict[str, Any]:
        self._check()
        return {"format": SENSOR_HEALTH_FORMAT, "false_finding_rate": self.false_finding_rate,
                "min_rise": self.min_rise, "offset_quantile": self.offset_quantile,
                "min_offset_m": self.min_offset_m,
                "max_share": self.max_share,
                "bands": {ch: {m: list(b) for m, b in bands.items()}
                          for ch, bands in self.bands_.items()},
                "floor_medians": self.floor_medians_}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> SensorBands:
        if d.get("format") != SENSOR_HEALTH_FORMAT:
            raise ValueError(f"not a {SENSOR_HEALTH_FORMAT} document")
        obj = cls(float(d["false_finding_rate"]), float(d["min_rise"]),
                  float(d["offset_quantile"]), float(d["min_offset_m"]), float(d["max_share"]))
        obj.bands_ = {str(ch): {str(m): (float(b[0]), float(b[1])) for m, b in bands.items()}
                      for ch, bands in d["bands"].items()}
        obj.floor_medians_ = {str(ch): float(v) for ch, v in d["floor_medians"].items()}
        return obj


# --------------------------------------------------------------------------------------------
# what a noisier sensor does to the features
# --------------------------------------------------------------------------------------------


def _floor_ratio(study: Mapping[str, Mapping[str, float]],
                 twin: Mapping[str, Mapping[str, float]], position: str, sensor: str) -> float:
    """The study flight's noise floor of the sensor over its twin's."""
    ch = f"{position}.{_FLOOR_OF[sensor]}"
    try:
        return study[ch]["noise"] / twin[ch]["noise"]
    except (KeyError, ZeroDivisionError):
        return math.nan


@dataclass
class _Pair:
    """One feature on one study flight and its twin: residuals, excess noise variance ``e``,
    evidence weight ``w`` and the feature's scale on its log (0 for a feature judged on its
    value)."""

    z_study: float
    z_twin: float
    e: float
    w: float
    log_scale: float


@dataclass
class NoiseSensitivity:
    """How a sensor's noise moves each generic feature's standardised residual.

    Learned on the design campaign's sensor study: healthy patterns flown twice, once as
    rigged and once with one sensor's noise raised (same flights, seeds and noise draws), so
    that each pair of flights differs by that sensor's noise alone, loops included. ``e =
    r^2 - 1`` is the pair's excess noise variance (``r``: the measured floor ratio) and ``w``
    the flight's evidence weight (``FleetBaseline.evidence_weights``).

    * **Bias of a feature judged on its value** (a slope such as F_TTS's): a feature averages
      its flight's valid windows, so its noise-driven error grows with the noise variance over
      the number of windows; per unit of ``e w`` the residual moves by ``bias_[g][s]``, the
      mean paired difference per unit ``e w``. Sensors add.
    * **Bias of a magnitude judged on its log** (``F_SE``, ``F_BDO``: amplitudes that noise
      inflates in power): a sensor's noise adds power to the flight's own, ``F^2 = F0^2 +
      N``, ``N = sum_s noise_power_[g][s] e_s`` in units of the healthy power the baseline
      expects (``z = 0``), so the noisier sensors add in power, and what is taken off is
      the flight's own share of it: ``F0^2 = F^2 - N``, on the log ``log(1 - N exp(-2 s
      z)) / 2`` for a flight at residual ``z`` (``s`` the feature's log scale). A healthy
      flight loses the whole shift, a fault's larger power little of it (a constant shift
      took the healthy flights' 1.6 residual units off a static eccentricity's flights too
      and hid it). The shift is never more than a flight at the healthy power loses,
      ``log(1 + N) / 2``: a quiet flight's ``F0^2`` estimate can fall to 0 or below.
      ``noise_power_`` is the study's mean ``(exp(2 s z_study) - exp(2 s z_twin)) / e``.
      No ``w``: taken as mostly noise, the healthy magnitude's noise share is the same at
      any number of windows (an assumption, not measured). A document fitted before
      (``power``: shares of the twin's power, a constant shift ``log(1 + sum_s power_s
      e_s) / 2``) is judged as it was fitted.
    * **Added scatter** per unit ``e w``, ``variance_[g][s]``: what the study flights' scatter
      gains over their twins', measured, not derived from a noise model:
      ``var(z_s) - var(z_t) = var(d) + 2 cov(d, z_t)`` for the pair difference ``d`` less
      its bias, within each study pattern and position (one actuator's flights), pooled over
      them and divided by their ``sum e w``; 0 when negative. An earlier estimator assumed the
      noise error scales by ``r`` (scatter ``(r^2 - 1) var(d) / (r - 1)^2``), three times the
      pair spread at ``r = 2``; on a magnitude judged on its log, where a louder noise moves
      the value and leaves its scatter, it widened bands by a variance of 3 for nothing and
      hid step faults (docs/TUNING.md, Sensor health).
    """

    def __post_init__(self) -> None:
        self.bias_: dict[str, dict[str, float]] = {}
        self.power_: dict[str, dict[str, float]] = {}
        self.noise_power_: dict[str, dict[str, float]] = {}
        self.variance_: dict[str, dict[str, float]] = {}
        self.log_scale_: dict[str, float] = {}

    def fit(self, pairs: Sequence[tuple[str, str, FlightFeatures, FlightFeatures]],
            baseline: Any) -> NoiseSensitivity:
        """``pairs``: ``(sensor, study pattern, study flight, twin flight)`` with their
        :class:`~server.phm.features.FlightFeatures`; ``baseline``: the fitted
        :class:`server.phm.baselines.FleetBaseline`."""
        self.log_scale_ = _log_scales(baseline)
        groups: dict[tuple[str, str, str], list[_Pair]] = {}
        for sensor, pattern, study, twin in pairs:
            z_s, z_t = baseline.zscores(study), baseline.zscores(twin)
            weights = baseline.evidence_weights(twin)
            for name, zt in z_t.items():
                _, positions = _feature_positions(name)
                e = float(np.mean([_floor_ratio(study.quality, twin.quality, p, sensor) ** 2
                                   - 1.0 for p in positions]))
                zs = z_s.get(name, math.nan)
                if math.isfinite(zs) and math.isfinite(zt) and e > 0.05:
                    groups.setdefault((name, sensor, pattern), []).append(
                        _Pair(zs, zt, e, weights.get(name, 1.0),
                              self.log_scale_.get(name, 0.0)))
        self.bias_ = {g: {} for g in FEATURE_SENSORS}
        self.power_ = {}
        self.noise_power_ = {g: {} for g in FEATURE_SENSORS}
        self.variance_ = {g: {} for g in FEATURE_SENSORS}
        by_generic: dict[tuple[str, str], list[list[_Pair]]] = {}
        for (name, sensor, _), rows in groups.items():
            if len(rows) >= 3:
                by_generic.setdefault((name.split(".", 1)[1], sensor), []).append(rows)
        for (g, sensor), sets in by_generic.items():
            if g not in FEATURE_SENSORS or sensor not in FEATURE_SENSORS[g]:
                continue
            if sets[0][0].log_scale > 0:
                noise = self.noise_power_[g][sensor] = _noise_power(sets)
                self.variance_[g][sensor] = _added_variance(sets, _log_bias(noise))
            else:
                bias = self.bias_[g][sensor] = _bias(sets)
                self.variance_[g][sensor] = _added_variance(sets, _linear_bias(bias))
        return self

    def fitted(self) -> bool:
        """Whether the study gave any coefficient (pairs too few or too alike give none)."""
        return any(self.variance_.values())

    def effect(self, name: str, excess: Mapping[str, float], weight: float = 1.0,
               z: float = 0.0) -> tuple[float, float]:
        """``(bias, added variance)`` of feature ``name`` (``"WT.F_SE"``) on a flight of
        evidence weight ``weight`` for the sensors' excess noise variances ``excess``
        (sensor -> r^2 - 1), in residual units; ``z``: the flight's residual (a magnitude on
        its log loses the noise's share of its own power)."""
        generic = name.split(".", 1)[1]
        var = sum(self.variance_.get(generic, {}).get(s, 0.0) * e for s, e in excess.items())
        scale = self.log_scale_.get(name, 0.0)
        if scale > 0 and generic in self.noise_power_:
            noise = sum(self.noise_power_[generic].get(s, 0.0) * e for s, e in excess.items())
            return _power_shift(noise, z * scale) / scale, var * weight
        if scale > 0 and generic in self.power_:
            power = sum(self.power_[generic].get(s, 0.0) * e for s, e in excess.items())
            # a share below -1 is no power; the floor keeps the log finite
            return 0.5 * math.log(max(1.0 + power, _MIN_POWER_RATIO)) / scale, var * weight
        bias = sum(self.bias_.get(generic, {}).get(s, 0.0) * e for s, e in excess.items())
        return bias * weight, var * weight

    def to_dict(self) -> dict[str, Any]:
        out = {"bias": self.bias_, "noise_power": self.noise_power_,
               "variance": self.variance_, "log_scale": self.log_scale_}
        if self.power_:
            out["power"] = self.power_
        return out

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> NoiseSensitivity:
        """A document written before the log features' power shares (no ``power``) is judged
        as it was fitted: every bias linear in ``e w``."""
        obj = cls()
        obj.bias_ = _coefficients(d["bias"])
        obj.power_ = _coefficients(d.get("power", {}))
        obj.noise_power_ = _coefficients(d.get("noise_power", {}))
        obj.variance_ = _coefficients(d["variance"])
        obj.log_scale_ = {k: float(v) for k, v in d.get("log_scale", {}).items()}
        return obj


#: the least power ratio a log feature's shift is computed at (a study share below -1/e)
_MIN_POWER_RATIO = 1e-2


def _coefficients(d: Mapping[str, Mapping[str, Any]]) -> dict[str, dict[str, float]]:
    return {g: {s: float(v) for s, v in m.items()} for g, m in d.items()}


def _log_scales(baseline: Any) -> dict[str, float]:
    """Feature -> its residual's scale in log units, for the features judged on their log."""
    logged = set(getattr(baseline, "log_features", ()))
    names = [n for n in baseline.feature_names_ if n.split(".", 1)[1] in logged]
    return {n: float(v) for n, v in baseline.to_physical(dict.fromkeys(names, 1.0)).items()}


def _significant_mean(x: np.ndarray) -> float:
    """The mean of ``x``; 0 unless beyond three standard errors (or fewer than 3 values)."""
    if x.size < 3:
        return 0.0
    mean, se = float(x.mean()), float(x.std(ddof=1) / math.sqrt(x.size))
    return mean if abs(mean) > 3.0 * se else 0.0


def _bias(sets: Sequence[Sequence[_Pair]]) -> float:
    """Mean paired difference per unit ``e w``; 0 unless beyond three standard errors."""
    return _significant_mean(np.array([(p.z_study - p.z_twin) / (p.e * p.w)
                                       for rows in sets for p in rows]))


def _noise_power(sets: Sequence[Sequence[_Pair]]) -> float:
    """A log feature's added power per unit ``e``, in units of the healthy power the baseline
    expects: ``(exp(2 s z_study) - exp(2 s z_twin)) / e``; 0 unless beyond three standard
    errors."""
    return _significant_mean(np.array([
        (math.exp(2.0 * p.z_study * p.log_scale) - math.exp(2.0 * p.z_twin * p.log_scale))
        / p.e for rows in sets for p in rows]))


def _power_shift(noise: float, log_value: float) -> float:
    """How far added noise power ``noise`` (in healthy power units) moved the log of a
    magnitude now ``log_value`` above the healthy one: ``-log(1 - noise exp(-2 log_value))
    / 2``, at most ``log(1 + noise) / 2``, the shift at the healthy power (a quiet flight's
    own power is known no better)."""
    at_healthy = 0.5 * math.log(max(1.0 + noise, _MIN_POWER_RATIO))
    own = 1.0 - noise * math.exp(-2.0 * log_value)
    if noise <= 0.0 or own <= 0.0:
        return at_healthy
    return min(-0.5 * math.log(own), at_healthy)


def _linear_bias(bias: float) -> Callable[[_Pair], float]:
    """A study flight's bias as judged, for a feature judged on its value."""
    return lambda p: bias * p.e * p.w


def _log_bias(noise: float) -> Callable[[_Pair], float]:
    """A study flight's bias as judged, for a magnitude judged on its log."""
    return lambda p: _power_shift(noise * p.e, p.z_study * p.log_scale) / p.log_scale


def _added_variance(sets: Sequence[Sequence[_Pair]], bias: Callable[[_Pair], float]) -> float:
    """Added flight scatter per unit ``e w``: ``var(d) + 2 cov(d, z_twin)`` within each group
    (``d`` the pair difference less the study flight's bias as judged, ``bias(pair)``),
    pooled, over the groups' ``sum e w``; 0 when negative. A magnitude's debiased power
    scatters more than its raw one where the noise's share is large: measured here."""
    num, den = 0.0, 0.0
    for rows in sets:
        zt = np.array([p.z_twin for p in rows])
        d = np.array([p.z_study - p.z_twin - bias(p) for p in rows])
        d, zt = d - d.mean(), zt - zt.mean()
        num += float(np.sum(d * (d + 2.0 * zt)))
        den += float(sum(p.e * p.w for p in rows))
    return max(num / den, 0.0) if den > 0 else 0.0


# --------------------------------------------------------------------------------------------
# judging a flight's features with its sensors' findings
# --------------------------------------------------------------------------------------------

#: findings after which a channel's values are no longer a measurement: its features are set
#: aside for the flight
_UNUSABLE = ("lsb", "stuck", "saturated")


@dataclass(frozen=True)
class SensorJudgement:
    """A flight's sensor findings and what they did to its residuals."""

    findings: list[SensorFinding]
    z: dict[str, float]  # residuals after the noise compensation (NaN: set aside)
    extra_variance: dict[str, float]  # feature -> added flight scatter [residual units^2]
    set_aside: list[str]  # features not judged on this flight

    def for_position(self, position: str) -> list[SensorFinding]:
        return [f for f in self.findings if f.position == position]


def _feature_positions(name: str) -> tuple[str, list[str]]:
    """``"WT.F_SE"`` -> ``("F_SE", ["WT"])``; a winglet drive's rod-end play reads the LVDTs
    and resolvers of both winglet drives."""
    position, generic = name.split(".", 1)
    return generic, list(WINGLET_PAIR) if generic == REWEAR_FEATURE else [position]


@dataclass
class SensorModel:
    """The healthy bands and the noise sensitivity of the features, learned on a design
    campaign; :meth:`judge` applies them to one flight."""

    bands: SensorBands
    sensitivity: NoiseSensitivity | None = None

    def _excess(self, quality: Mapping[str, Mapping[str, float]],
                findings: Sequence[SensorFinding]) -> dict[str, dict[str, float]]:
        """position -> sensor -> excess noise variance ``r^2 - 1`` of the sensors whose
        noise floor is above its band (``r``: the floor over its healthy median)."""
        noisy = {(f.position, f.sensor) for f in findings
                 if f.metric == "noise" and f.value > f.high}
        out: dict[str, dict[str, float]] = {}
        for p, sensor in noisy:
            ratios = [quality[ch]["noise"] / median
                      for ch, median in self.bands.floor_medians_.items()
                      if channel_sensor(ch) == (p, sensor)
                      and math.isfinite(quality.get(ch, {}).get("noise", math.nan))]
            if ratios:
                out.setdefault(p, {})[sensor] = max(float(np.median(ratios)) ** 2 - 1.0, 0.0)
        return out

    def judge(self, quality: Mapping[str, Mapping[str, float]], z: Mapping[str, float],
              evidence: Mapping[str, float] | None = None) -> SensorJudgement:
        """Findings of the flight's signal-quality figures, and the residuals ``z``
        (feature -> value) judged with them: a feature reading an unusable channel (coarser
        step, stuck or clipped) is set aside; one reading a noisier sensor is compensated
        for its bias and gets the added scatter (without a learned sensitivity it is set
        aside). ``evidence``: each feature's evidence weight (``FleetBaseline.evidence_weights``;
        1 where not given). No finding, no change."""
        findings = self.bands.assess(quality)
        if not findings:
            return SensorJudgement([], dict(z), {}, [])
        unusable = {(f.position, f.sensor) for f in findings if f.metric in _UNUSABLE}
        excess = self._excess(quality, findings)
        compensate = self.sensitivity is not None and self.sensitivity.fitted()
        if not compensate:
            unusable |= {(p, s) for p, m in excess.items() for s in m}
        out, extra, aside = dict(z), {}, []
        for name in z:
            generic, positions = _feature_positions(name)
            reads = [(p, s) for p in positions for s in FEATURE_SENSORS.get(generic, ())]
            if any(r in unusable for r in reads):
                out[name] = math.nan
                aside.append(name)
                continue
            e = {s: sum(excess.get(p, {}).get(s, 0.0) for p in positions) / len(positions)
                 for s in FEATURE_SENSORS.get(generic, ())}
            if compensate and any(v > 0 for v in e.values()):
                # compensate is only true with a sensitivity model
                bias, var = self.sensitivity.effect(  # type: ignore[union-attr]
                    name, e, (evidence or {}).get(name, 1.0), z[name])
                out[name] = z[name] - bias
                extra[name] = var
        return SensorJudgement(findings, out, extra, aside)

    def to_dict(self) -> dict[str, Any]:
        return {"bands": self.bands.to_dict(),
                "sensitivity": None if self.sensitivity is None else self.sensitivity.to_dict()}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> SensorModel:
        sens = d.get("sensitivity")
        return cls(SensorBands.from_dict(d["bands"]),
                   None if sens is None else NoiseSensitivity.from_dict(sens))


def fit_sensor_model(healthy: Sequence[FlightFeatures],
                     pairs: Sequence[tuple[str, str, FlightFeatures, FlightFeatures]],
                     baseline: Any) -> SensorModel | None:
    """The sensor model of a design campaign: bands from its healthy flights' figures, the
    noise sensitivity from its sensor study's ``(sensor, study pattern, study flight, twin
    flight)`` pairs (none without a study). None when no flight carries signal-quality
    figures (features stored before they existed)."""
    qualities = [f.quality for f in healthy if f.quality]
    if not qualities:
        return None
    sensitivity = NoiseSensitivity().fit(pairs, baseline) if pairs else None
    return SensorModel(SensorBands().fit(qualities), sensitivity)
