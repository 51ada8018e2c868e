"""The fitted detector: each feature's offset components, its evidence share and its healthy
bands, learned on the healthy design flights, and the JSON document that carries them
(``ema-detector/2``, never pickle).

Bands for a stated false-alarm rate
-----------------------------------
The bands are set for ``false_alarm_rate`` (alarms per monitored unit and healthy flight). The
rate is shared out among the unit's tests, every (feature, window) allowed to alarm
(``min_windows``), by Sidak's rule: each test may exceed its threshold on a healthy flight with
probability ``q = 1 - (1 - false_alarm_rate)^(1/m)``, ``m`` the unit's tests (a two-sided
feature gives ``q / 2`` to each tail). The healthy statistic is modelled as
``S_w ~ N(0, s_w^2)``; ``s_w`` is measured on the healthy design flights by matching the upper
``scale_quantile`` quantile of their judged ``S_w`` (what the online judge would alarm on,
:func:`~server.phm.detection.sequences.healthy_statistics`; a surface's positions together
with ``pool_positions``), ``s_w = Q_p(S_w) / z_p``: a tail quantile rather than an RMS or a MAD,
because the healthy tails are heavier than normal. A test alarms at ``s_w z_{1-q}``; with the
confidence margin ``z_alarm = ndtri(alarm_confidence)`` the band is

    b_w = max(s_w z_{1-q} - z_alarm, band_floor).

``Q_p`` estimates a fixed quantile of the healthy population, so the band's expected value does
not depend on how many healthy design flights there are (only its precision does), unlike the
largest healthy ``|S_w|``, which grows with them. A sample quantile needs a few values beyond
it: on a small pool it is low and noisy, and those bands mostly rest on the floor. Under the
normal model the realised rate is at most the stated one (windows overlap and a unit's tests
are correlated; Sidak's share is the independent case's); a tail heavier than normal beyond
``Q_p`` raises it.

The offsets (``within_std_``, ``between_std_``: :mod:`.statistics`) and the evidence shares
(``evidence_variance_``: :mod:`.evidence`) are learned first, on the same flights.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from types import MappingProxyType
from typing import Any

import numpy as np
from scipy.special import ndtri

from server.vocabulary import is_winglet

from .config import DETECTION_DEFAULTS, DetectionConfig, generic_feature, unit_of
from .evidence import at_typical_evidence, evidence_shares
from .sequences import healthy_statistics
from .statistics import offset_components, self_referenced_sequence

__all__ = ["DETECTOR_FORMAT", "FaultDetector"]

DETECTOR_FORMAT = "ema-detector/2"
#: /1 bands were the largest healthy ``|S_w|``; its documents load with the bands they carry
_DETECTOR_FORMATS = (DETECTOR_FORMAT, "ema-detector/1")


def _generic_groups(names: Sequence[str], split: Sequence[str] = ()) -> list[list[int]]:
    """Column indices of each generic feature (``WL1.F_TTS``, ``WT.F_TTS`` -> one group); a
    generic feature in ``split`` gives one group per surface (``WL1.F_MTWEAR`` and
    ``WL2.F_MTWEAR`` one, ``WT.F_MTWEAR`` another)."""
    gen = [generic_feature(n) for n in names]
    key = [(g, g not in split or is_winglet(unit_of(n))) for n, g in zip(names, gen, strict=True)]
    return [[i for i, x in enumerate(key) if x == k] for k in dict.fromkeys(key)]


def _surfaces_apart(names: Sequence[str], seqs: Sequence[np.ndarray], ratio: float
                    ) -> list[str]:
    """Generic features whose within-unit scatter on one surface exceeds the other's by more
    than ``ratio`` on these healthy sequences (each surface's positions together)."""
    if not math.isfinite(ratio):
        return []
    sigma, _ = offset_components(seqs)
    apart = []
    for idx in _generic_groups(names):
        by_surface: dict[bool, list[float]] = {}
        for i in idx:
            by_surface.setdefault(is_winglet(unit_of(names[i])), []).append(sigma[i] ** 2)
        if len(by_surface) < 2:
            continue
        scatter = [math.sqrt(float(np.mean(v))) for v in by_surface.values()]
        if max(scatter) > ratio * min(scatter):
            apart.append(generic_feature(names[idx[0]]))
    return apart


class FaultDetector:
    """Separation-confidence detector with bands learned on healthy design flights.

    Parameters: the fields of :class:`~server.phm.detection.config.DetectionConfig` (units and
    reasons there), defaults :data:`DETECTION_DEFAULTS`; ``None`` for a mapping or
    ``fleet_referenced`` is its default. The online judge
    (:func:`~server.phm.detection.judge.update_units`) and its vectorised form
    (:mod:`~server.phm.detection.sequences`) read a fitted detector; they never change it.
    """

    def __init__(self, windows: Sequence[int] = DETECTION_DEFAULTS.windows, *,
                 alarm_confidence: float = DETECTION_DEFAULTS.alarm_confidence,
                 band_floor: float = DETECTION_DEFAULTS.band_floor,
                 false_alarm_rate: float = DETECTION_DEFAULTS.false_alarm_rate,
                 scale_quantile: float = DETECTION_DEFAULTS.scale_quantile,
                 directions: Mapping[str, int] | None = None,
                 pool_positions: bool = DETECTION_DEFAULTS.pool_positions,
                 surface_split_ratio: float = DETECTION_DEFAULTS.surface_split_ratio,
                 min_windows: Mapping[str, int] | None = None,
                 reference_flights: int = DETECTION_DEFAULTS.reference_flights,
                 window_clip: float = DETECTION_DEFAULTS.window_clip,
                 median_from: int = DETECTION_DEFAULTS.median_from,
                 fleet_referenced: Sequence[str] | None = None) -> None:
        if not windows or min(windows) < 1:
            raise ValueError("windows must be positive flight counts")
        if not 0.5 < alarm_confidence < 1.0:
            raise ValueError("alarm_confidence must lie in (0.5, 1)")
        self.windows = tuple(int(w) for w in windows)
        self.alarm_confidence = float(alarm_confidence)
        self.band_floor = float(band_floor)
        if false_alarm_rate is None or not 0.0 < false_alarm_rate < 1.0:
            raise ValueError("false_alarm_rate must lie in (0, 1)")
        self.false_alarm_rate: float | None = float(false_alarm_rate)
        if not 0.5 < scale_quantile < 1.0:
            raise ValueError("scale_quantile must lie in (0.5, 1)")
        self.scale_quantile = float(scale_quantile)
        self.directions = dict(DETECTION_DEFAULTS.directions if directions is None
                               else directions)
        self.pool_positions = bool(pool_positions)
        if not surface_split_ratio >= 1.0:
            raise ValueError("surface_split_ratio must be at least 1 (inf: never split)")
        self.surface_split_ratio = float(surface_split_ratio)
        #: generic features fitted per surface (set by :meth:`fit`)
        self.surface_split_: list[str] = []
        self.min_windows = dict(DETECTION_DEFAULTS.min_windows if min_windows is None
                                else min_windows)
        if reference_flights < 0:
            raise ValueError("reference_flights must be >= 0")
        self.reference_flights = int(reference_flights)
        if not window_clip > 0:
            raise ValueError("window_clip must be positive")
        self.window_clip = float(window_clip)
        self.median_from = int(median_from)
        self.fleet_referenced = tuple(DETECTION_DEFAULTS.fleet_referenced
                                      if fleet_referenced is None else fleet_referenced)

    @classmethod
    def from_config(cls, config: DetectionConfig) -> FaultDetector:
        """An unfitted detector with the hyper-parameters of ``config``."""
        return cls(config.windows, alarm_confidence=config.alarm_confidence,
                   band_floor=config.band_floor, false_alarm_rate=config.false_alarm_rate,
                   scale_quantile=config.scale_quantile,
                   directions=config.directions, pool_positions=config.pool_positions,
                   surface_split_ratio=config.surface_split_ratio,
                   min_windows=config.min_windows, reference_flights=config.reference_flights,
                   window_clip=config.window_clip, median_from=config.median_from,
                   fleet_referenced=config.fleet_referenced)

    @property
    def config(self) -> DetectionConfig:
        """This detector's hyper-parameters (``false_alarm_rate`` is None for bands loaded
        from an ``ema-detector/1`` document: those were the largest healthy ``|S_w|``)."""
        return DetectionConfig(
            windows=self.windows, alarm_confidence=self.alarm_confidence,
            band_floor=self.band_floor,
            # None for bands loaded from an ema-detector/1 document (docstring)
            false_alarm_rate=self.false_alarm_rate,  # type: ignore[arg-type]
            scale_quantile=self.scale_quantile,
            directions=MappingProxyType(dict(self.directions)),
            pool_positions=self.pool_positions, surface_split_ratio=self.surface_split_ratio,
            min_windows=MappingProxyType(dict(self.min_windows)),
            reference_flights=self.reference_flights, window_clip=self.window_clip,
            median_from=self.median_from, fleet_referenced=self.fleet_referenced)

    # -- what the hyper-parameters say about one feature or window -------------------------

    def min_window(self, name: str) -> int:
        """Shortest window of feature ``name`` allowed to raise an alarm [flight]."""
        return int(self.min_windows.get(generic_feature(name), 1))

    def direction(self, name: str) -> int:
        """The fault's direction on feature ``name``: +1, -1, or 0 (either)."""
        return int(self.directions.get(generic_feature(name), 0))

    def directions_of(self, names: Sequence[str]) -> np.ndarray:
        """:meth:`direction` of each of ``names`` (n_features,)."""
        return np.array([self.direction(n) for n in names], dtype=np.float64)

    def uses_median(self, window: int) -> bool:
        """Whether a window of this many flights is judged on its median."""
        return 0 < self.median_from <= window

    def clipped(self, z: np.ndarray, window: int) -> np.ndarray:
        """Residuals as a window of this many flights sees them: clipped to
        ``+-window_clip`` unless it is one flight."""
        return z if window == 1 else np.clip(z, -self.window_clip, self.window_clip)

    @property
    def z_alarm(self) -> float:
        """Standard errors beyond the band at which the confidence reaches the alarm level."""
        return float(ndtri(self.alarm_confidence))

    # -- fitting -------------------------------------------------------------------------

    def fit(self, healthy_sequences: Sequence[np.ndarray],
            feature_names: Sequence[str],
            evidence: Sequence[np.ndarray] | None = None) -> FaultDetector:
        """Learn the bands from healthy flight sequences of the design campaign.

        ``healthy_sequences``: one (n_flights_i, n_features) array of standardised residuals per
        history (flights in order; an aircraft's columns together, so that the winglet pair is
        judged as the online judge judges it), columns in ``feature_names`` order;
        ``evidence``: the flights' evidence weights, same shapes (None: every flight typical).
        First the sampling share of the scatter (:mod:`.evidence`), then the offset components
        (``sigma``, ``tau``) per generic feature at typical evidence, then each (feature,
        window)'s healthy scale ``s_w`` on the judged statistics of the same sequences, and its
        band for ``false_alarm_rate`` (module docstring).
        """
        names = list(feature_names)
        seqs = [np.asarray(q, dtype=np.float64).reshape(-1, len(names))
                for q in healthy_sequences]
        weights = (None if evidence is None else
                   [np.asarray(e, dtype=np.float64).reshape(-1, len(names)) for e in evidence])
        self.surface_split_ = (_surfaces_apart(names, seqs, self.surface_split_ratio)
                               if self.pool_positions else [])
        share = np.zeros(len(names))
        if weights is not None and self.reference_flights > 0:
            share = evidence_shares(seqs, weights, self._pools(names))
        typical = (seqs if weights is None else
                   [at_typical_evidence(q, e, share) for q, e in zip(seqs, weights, strict=True)])
        if self.reference_flights == 0:  # the fleet test: z as it is
            sigma, tau = np.ones(len(names)), np.zeros(len(names))
        else:
            sigma, tau = offset_components(typical)
            if self.pool_positions:  # one actuator population per generic feature
                for idx in self._pools(names):
                    sigma[idx] = np.sqrt(np.mean(sigma[idx] ** 2))
                    tau[idx] = np.sqrt(np.mean(tau[idx] ** 2))
            self.evidence_variance_ = share * sigma**2
            fleet = np.array([generic_feature(n) in self.fleet_referenced for n in names],
                             dtype=bool)
            sigma[fleet] = np.sqrt(sigma[fleet] ** 2 + tau[fleet] ** 2)
            tau[fleet] = 0.0  # no offset to learn: the reference is the fleet's
        if self.reference_flights == 0:
            self.evidence_variance_ = np.zeros(len(names))
        self.within_std_, self.between_std_ = sigma, tau
        seen = np.zeros(len(names), dtype=np.int64)
        for seq in seqs:
            seen += np.isfinite(seq).sum(axis=0)
        self.feature_names_ = names
        stats = healthy_statistics(self, seqs, names, weights)
        groups = self._pools(names)
        scale = np.full((len(names), len(self.windows)), np.nan)
        for idx in groups:
            two_sided = self.direction(names[idx[0]]) == 0
            for k in range(len(self.windows)):
                scale[idx, k] = self._scale_of(np.concatenate([stats[k][i] for i in idx]),
                                               two_sided)
        self.healthy_scale_ = scale
        self.band_ = self._bands_for(scale)
        self.n_healthy_flights_ = seen
        return self

    def _pools(self, names: Sequence[str]) -> list[list[int]]:
        """Column indices fitted as one population (``pool_positions``, ``surface_split_``)."""
        if not self.pool_positions:
            return [[i] for i in range(len(names))]
        return _generic_groups(names, self.surface_split_)

    def _scale_of(self, s: np.ndarray, two_sided: bool) -> float:
        """Normal scale of healthy judged statistics: their ``scale_quantile`` quantile (Weibull
        plotting position, ``p (N + 1)``) over the standard-normal one (of ``|S|`` for a
        two-sided feature); NaN without any."""
        if not s.size:
            return math.nan
        p = self.scale_quantile
        z_p = float(ndtri(0.5 + p / 2) if two_sided else ndtri(p))
        return float(np.quantile(s, p, method="weibull")) / z_p

    def tests_per_unit(self, feature_names: Sequence[str] | None = None) -> dict[str, int]:
        """Unit -> its tests, the (feature, window) pairs allowed to alarm."""
        names = self.feature_names_ if feature_names is None else list(feature_names)
        out: dict[str, int] = {}
        for n in names:
            unit = unit_of(n)
            out[unit] = out.get(unit, 0) + sum(w >= self.min_window(n) for w in self.windows)
        return out

    def test_quantiles(self, feature_names: Sequence[str] | None = None) -> np.ndarray:
        """``z_{1-q}`` of every feature's tests (n_features,): the standard-normal quantile of
        its share ``q`` of its unit's false-alarm rate (Sidak; ``q / 2`` per side for a
        two-sided feature)."""
        if self.false_alarm_rate is None:
            raise RuntimeError("an ema-detector/1 document states no false-alarm rate")
        names = self.feature_names_ if feature_names is None else list(feature_names)
        m = self.tests_per_unit(names)
        per_test = np.array([-math.expm1(math.log1p(-self.false_alarm_rate)
                                         / max(m[unit_of(n)], 1)) for n in names])
        two_sided = self.directions_of(names) == 0
        return -ndtri(np.where(two_sided, per_test / 2, per_test))

    def _bands_for(self, scale: np.ndarray) -> np.ndarray:
        """Bands (n_features, n_windows) of healthy scales ``s_w``: the alarm threshold
        ``s_w z_{1-q}`` less the confidence margin, floored; no healthy value -> the floor."""
        thr = scale * self.test_quantiles()[:, np.newaxis]
        band = np.fmax(thr - self.z_alarm, self.band_floor)
        return np.where(np.isfinite(band), band, self.band_floor)

    # -- the fitted model --------------------------------------------------------------------

    def check_fitted(self) -> None:
        if not hasattr(self, "band_"):
            raise RuntimeError("FaultDetector is not fitted")

    def bands(self) -> dict[str, list[float]]:
        """Feature -> band per window (standard errors)."""
        self.check_fitted()
        return {n: self.band_[i].tolist() for i, n in enumerate(self.feature_names_)}

    def self_referenced(self, z: np.ndarray, extra_variance: np.ndarray | None = None
                        ) -> np.ndarray:
        """Self-referenced residuals of one history (n_flights, all features);
        ``extra_variance`` (same shape) adds to each flight's scatter."""
        return self_referenced_sequence(z, self.within_std_, self.between_std_,
                                        self.reference_flights, extra_variance)

    def evidence_extra(self, weights: np.ndarray,
                       feature_names: Sequence[str] | None = None) -> np.ndarray:
        """The extra variance of flights with evidence weights ``weights`` (..., n_features in
        ``feature_names`` order, default the fitted ones): ``sigma^2 a (w - 1)``, 0 where no
        weight is known."""
        names = self.feature_names_ if feature_names is None else list(feature_names)
        idx = [self.feature_names_.index(n) for n in names]
        w = np.asarray(weights, dtype=np.float64)
        return np.where(np.isfinite(w), self.evidence_variance_[idx] * (w - 1.0), 0.0)

    def flight_variance(self, evidence: Mapping[str, float] | None = None,
                        extra_variance: Mapping[str, float] | None = None) -> dict[str, float]:
        """Feature -> variance added to one flight's scatter: its evidence's
        (:meth:`evidence_extra`) and a noisier sensor's (``extra_variance``)."""
        out = dict(extra_variance or {})
        for f, w in (evidence or {}).items():
            if f in self.feature_names_ and math.isfinite(w):
                i = self.feature_names_.index(f)
                if self.evidence_variance_[i]:
                    out[f] = out.get(f, 0.0) + float(self.evidence_variance_[i] * (w - 1.0))
        return out

    def to_dict(self) -> dict[str, Any]:
        self.check_fitted()
        return {"format": DETECTOR_FORMAT, "windows": list(self.windows),
                "alarm_confidence": self.alarm_confidence, "band_floor": self.band_floor,
                "false_alarm_rate": self.false_alarm_rate,
                "scale_quantile": self.scale_quantile, "directions": dict(self.directions),
                "pool_positions": self.pool_positions,
                "surface_split_ratio": (self.surface_split_ratio
                                        if math.isfinite(self.surface_split_ratio) else None),
                "min_windows": dict(self.min_windows),
                "reference_flights": self.reference_flights,
                "window_clip": self.window_clip if math.isfinite(self.window_clip) else None,
                "median_from": self.median_from,
                "fleet_referenced": list(self.fleet_referenced),
                "within_std": self.within_std_.tolist(),
                "between_std": self.between_std_.tolist(),
                "evidence_variance": self.evidence_variance_.tolist(),
                "surface_split": list(self.surface_split_),
                "feature_names": list(self.feature_names_),
                "band": self.band_.tolist(),
                "healthy_scale": [[v if math.isfinite(v) else None for v in row]
                                  for row in self.healthy_scale_.tolist()],
                "n_healthy_flights": self.n_healthy_flights_.tolist()}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> FaultDetector:
        """A fitted detector from its document; an ``ema-detector/1`` one (bands the largest
        healthy ``|S_w|``, no rate) keeps its bands, with ``false_alarm_rate`` None."""
        if d.get("format") not in _DETECTOR_FORMATS:
            raise ValueError(f"not a {DETECTOR_FORMAT} document")
        legacy = d["format"] != DETECTOR_FORMAT
        det = cls(d["windows"], alarm_confidence=float(d["alarm_confidence"]),
                  band_floor=float(d["band_floor"]),
                  false_alarm_rate=float(d.get("false_alarm_rate")
                                         or DETECTION_DEFAULTS.false_alarm_rate),
                  scale_quantile=float(d.get("scale_quantile")
                                       or DETECTION_DEFAULTS.scale_quantile),
                  directions={k: int(v) for k, v in d.get("directions", {}).items()},
                  pool_positions=bool(d.get("pool_positions", False)),
                  # a document without it pooled every position of a generic feature
                  surface_split_ratio=math.inf if d.get("surface_split_ratio") is None
                  else float(d["surface_split_ratio"]),
                  min_windows={k: int(v) for k, v in d.get("min_windows", {}).items()},
                  reference_flights=int(d.get("reference_flights", 0)),
                  window_clip=math.inf if d.get("window_clip") is None
                  else float(d["window_clip"]),
                  median_from=int(d.get("median_from", 0)),
                  fleet_referenced=tuple(d.get("fleet_referenced", ())))
        det.surface_split_ = list(d.get("surface_split", []))
        det.feature_names_ = list(d["feature_names"])
        n = len(det.feature_names_)
        det.within_std_ = np.asarray(d.get("within_std", np.ones(n)), dtype=np.float64)
        det.between_std_ = np.asarray(d.get("between_std", np.zeros(n)), dtype=np.float64)
        # a document without it kept one scatter whatever a flight's evidence
        det.evidence_variance_ = np.asarray(d.get("evidence_variance", np.zeros(n)),
                                            dtype=np.float64)
        det.band_ = np.asarray(d["band"], dtype=np.float64).reshape(len(det.feature_names_),
                                                                    len(det.windows))
        scale = d.get("healthy_scale")
        det.healthy_scale_ = (np.full(det.band_.shape, np.nan) if scale is None else np.array(
            [[math.nan if v is None else float(v) for v in row] for row in scale],
            dtype=np.float64).reshape(det.band_.shape))
        if legacy:
            det.false_alarm_rate = None
        det.n_healthy_flights_ = np.asarray(d["n_healthy_flights"], dtype=np.int64)
        return det
