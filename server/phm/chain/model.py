"""The trained chain as one JSON document (``ema-phm-model/5``): baselines, detector,
classifier, one measurement spec per progressive mode, the filter's configuration, the bases'
climate. :func:`read_model_document` is the one reader of that document."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from ..baselines import FleetBaseline
from ..classification import FaultClassifier
from ..classification.crosstalk import CrossTalk
from ..detection import DetectionState, FaultDetector
from ..prognosis import MeasurementModel, PrognoserConfig
from ..prognosis.calibration import BandCalibration
from ..season import SeasonalClimate
from ..sensor_health import SensorModel
from .inputs import actuator_feature_names, surface_of
from .state import ActuatorHealth

__all__ = ["MODEL_FORMAT", "MeasurementSpec", "PhmModel", "is_model_document",
           "read_model_document"]

#: /5: thermal modes age on the season's stress clock (the model carries the bases' climate).
#: A model of an older format was fitted on other feature definitions and is refused
MODEL_FORMAT = "ema-phm-model/5"
_OLD_MODEL_FORMATS = ("ema-phm-model/1", "ema-phm-model/2", "ema-phm-model/3",
                      "ema-phm-model/4")


@dataclass(frozen=True)
class MeasurementSpec:
    """Which generic feature tracks a progressive mode, how it depends on severity, and the
    mode's filter configuration (first-trial degradation parameters from the design runs)."""

    feature: str
    model: MeasurementModel
    prognoser: PrognoserConfig | None = None
    #: surface-specific models ("WL" for the winglet pair, "WT" for the wingtip) where the
    #: design runs had enough flights: the same wear shows differently on a drive that shares
    #: its surface with a second drive than on a lone one
    by_surface: dict[str, MeasurementModel] = field(default_factory=dict)
    #: temperature sensitivity of the mode's ageing [1/K] and its reference temperature
    #: [degC]: the filter's clock adds exp(beta (T - T_ref)) per flight (server.phm.season);
    #: beta = 0 is a flight clock; T_ref None is each base's own annual mean
    stress_beta_per_k: float = 0.0
    stress_ref_c: float | None = None
    #: replay the filter from the growth's estimated onset instead of from the alarm: for
    #: faults that grow along a straight line (wear), whose flights between onset and alarm
    #: already carry the rate
    replay_from_onset: bool = False
    #: surface-specific filters where the design runs showed the degradation law differs by
    #: surface (winglet wear slows down as the partner drive takes the load)
    prognoser_by_surface: dict[str, PrognoserConfig] = field(default_factory=dict)
    #: the RUL bands' calibration layer, fitted on replays of calibration design runs
    #: (``hmsm calibrate``); None: the filter's bands as they are
    band_calibration: BandCalibration | None = None

    def model_for(self, position: str) -> MeasurementModel:
        return self.by_surface.get(surface_of(position), self.model)

    def config_for(self, position: str) -> PrognoserConfig | None:
        return self.prognoser_by_surface.get(surface_of(position), self.prognoser)

    def to_dict(self) -> dict[str, Any]:
        return {"feature": self.feature, "model": self.model.to_dict(),
                "prognoser": None if self.prognoser is None else self.prognoser.to_dict(),
                "by_surface": {k: m.to_dict() for k, m in self.by_surface.items()},
                "stress_beta_per_k": self.stress_beta_per_k, "stress_ref_c": self.stress_ref_c,
                "replay_from_onset": self.replay_from_onset,
                "prognoser_by_surface": {k: c.to_dict()
                                         for k, c in self.prognoser_by_surface.items()},
                **({} if self.band_calibration is None
                   else {"band_calibration": self.band_calibration.to_dict()})}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> MeasurementSpec:
        cfg = d.get("prognoser")
        return cls(str(d["feature"]), MeasurementModel.from_dict(dict(d["model"])),
                   None if cfg is None else PrognoserConfig.from_dict(dict(cfg)),
                   {k: MeasurementModel.from_dict(dict(m))
                    for k, m in (d.get("by_surface") or {}).items()},
                   float(d.get("stress_beta_per_k", 0.0)),
                   None if d.get("stress_ref_c") is None else float(d["stress_ref_c"]),
                   bool(d.get("replay_from_onset", False)),
                   {k: PrognoserConfig.from_dict(dict(c))
                    for k, c in (d.get("prognoser_by_surface") or {}).items()},
                   None if d.get("band_calibration") is None
                   else BandCalibration.from_dict(d["band_calibration"]))


@dataclass
class PhmModel:
    """Everything the chain needs at run time, fitted on a design campaign."""

    baseline: FleetBaseline
    detector: FaultDetector
    classifier: FaultClassifier | None
    measurement: dict[str, MeasurementSpec]
    prognoser: PrognoserConfig = field(default_factory=PrognoserConfig)
    #: annual temperature cycle of each base (the stress clock's temperatures); None: flights
    climate: SeasonalClimate | None = None
    #: healthy bands of the signal-quality figures and the features' noise sensitivity;
    #: None (a document without them): no sensor findings, every feature judged as it is
    sensors: SensorModel | None = None
    #: the design's cross-talk limits of a second mode's own feature; None (a document
    #: without them): a second mode is named by its own probability alone
    crosstalk: CrossTalk | None = None

    def to_dict(self) -> dict[str, Any]:
        return {"format": MODEL_FORMAT, "baseline": self.baseline.to_dict(),
                "detector": self.detector.to_dict(),
                "classifier": None if self.classifier is None else self.classifier.to_dict(),
                "measurement": {m: s.to_dict() for m, s in self.measurement.items()},
                "prognoser": self.prognoser.to_dict(),
                "climate": None if self.climate is None else self.climate.to_dict(),
                "sensors": None if self.sensors is None else self.sensors.to_dict(),
                **({} if self.crosstalk is None else {"crosstalk": self.crosstalk.to_dict()})}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> PhmModel:
        if d.get("format") in _OLD_MODEL_FORMATS:
            raise ValueError(f"this model version was trained by an older chain "
                             f"({d.get('format')}); train a new one (hmsm train)")
        if d.get("format") != MODEL_FORMAT:
            raise ValueError(f"not a {MODEL_FORMAT} document")
        clf = d.get("classifier")
        return cls(FleetBaseline.from_dict(d["baseline"]), FaultDetector.from_dict(d["detector"]),
                   None if clf is None else FaultClassifier.from_dict(clf),
                   {m: MeasurementSpec.from_dict(s) for m, s in d["measurement"].items()},
                   PrognoserConfig.from_dict(dict(d["prognoser"])),
                   None if d.get("climate") is None else SeasonalClimate.from_dict(d["climate"]),
                   None if d.get("sensors") is None else SensorModel.from_dict(d["sensors"]),
                   None if d.get("crosstalk") is None else CrossTalk.from_dict(d["crosstalk"]))

    def new_health(self, position: str) -> ActuatorHealth:
        known = set(self.detector.feature_names_)
        feats = [f for f in actuator_feature_names(position) if f in known]
        return ActuatorHealth(position=position, detection=DetectionState.new(position, feats))


def read_model_document(doc: Mapping[str, Any]) -> PhmModel:
    """A model from its JSON document, or from a model-version record that wraps it in its
    ``payload`` field (``{"payload": <document>, ...}``)."""
    return PhmModel.from_dict(_unwrap(doc))


def is_model_document(doc: Any) -> bool:
    """Whether ``doc`` (or the record wrapping it) is in this chain's format, the one
    :func:`read_model_document` reads: not the empty payload of a version not trained yet,
    nor the document of an older chain."""
    return isinstance(doc, Mapping) and _unwrap(doc).get("format") == MODEL_FORMAT


def _unwrap(doc: Mapping[str, Any]) -> Mapping[str, Any]:
    if doc.get("format") != MODEL_FORMAT and isinstance(doc.get("payload"), Mapping):
        return doc["payload"]
    return doc
