"""The model the demo starts with, shipped in the package (``server/data/demo_model.json``).

Training a model on the demo's first run means simulating a design campaign first: minutes on
two cores before the URL appears. The demo instead starts on a model trained by our own
commands on a seeded design campaign -- the ``DESIGN_SCALE`` design campaign of seed
``DESIGN_SEED`` (long healthy cycles of 300-400 flights, recordings of 60, 120 and 300 s, the
test station's conditions: what a fleet and the station fly, sim_worker/campaign/), streamed,
trained with seed ``TRAINING_SEED`` -- and ships the result. ``hmsm demo-model --out FILE``
regenerates it (16 minutes on 2 idle cores); the RUL bands' calibration layers are then added by
``hmsm calibrate`` on replays of three calibration designs, one per band of fault speeds
(``bench/rul_suite.py calibration-stream`` and ``calibrate``, docs/RESULTS.md). The suite
cannot simulate that design in its budget: it checks the shipped document's provenance
against today's code (``tests/test_demo.py``), and
``HMSM_SHIPPED_DESIGN=DIR`` makes it retrain from a streamed copy of the design and compare.

The document: ``{"format": "ema-demo-model/1", "design": {"kind", "scale", "seed",
"healthy_cycle_flights", "recordings_s", "condition_blocks", "feature_version"},
"training_seed": ..., "leave_one_aircraft_out_healthy_rate": {...}, "payload": <ema-phm-model
document>, "training": <training report>}``; the report is stored without what depends on the
machine (timings, the campaign's directory). The healthy rate is the detector's on its own
design's healthy lives, each aircraft's judged by baselines fitted without it.
"""

from __future__ import annotations

import json
import tempfile
from importlib import resources
from pathlib import Path
from typing import Any

__all__ = ["DESIGN_SEED", "DESIGN_SCALE", "TRAINING_SEED", "FORMAT", "TRAINED_MODEL_FORMAT",
           "check_design", "design_record", "demo_model_document", "load_demo_model",
           "portable_report", "trained_model_document", "write_demo_model"]

DESIGN_SEED = 1
DESIGN_SCALE = "shipped"
TRAINING_SEED = 0
FORMAT = "ema-demo-model/1"
#: a model trained by ``hmsm train DIR --out FILE``: the chain's document in ``payload``
TRAINED_MODEL_FORMAT = "ema-trained-model/1"
_MACHINE_KEYS = ("timings_s",)


def _without_timings(value: Any) -> Any:
    if isinstance(value, dict):
        return {k: _without_timings(v) for k, v in value.items() if k not in _MACHINE_KEYS}
    if isinstance(value, list):
        return [_without_timings(v) for v in value]
    return value


def portable_report(report: dict[str, Any]) -> dict[str, Any]:
    """The training report without the machine's timings (at any depth) and the campaign's
    directory."""
    out = _without_timings(json.loads(json.dumps(report)))
    out["campaign"] = {k: v for k, v in (out.get("campaign") or {}).items() if k != "dir"}
    return out


def trained_model_document(fmt: str, design: dict[str, Any], training_seed: int,
                           payload: dict[str, Any], report: dict[str, Any]) -> dict[str, Any]:
    """A model document with where it was trained and its portable training report (the
    shape of the demo's and of a protocol run's ``model.json``)."""
    return {"format": fmt, "design": design, "training_seed": training_seed,
            "payload": json.loads(json.dumps(payload)), "training": portable_report(report)}


def design_record() -> dict[str, Any]:
    """What the shipped model's design campaign is, by today's code: its scale's healthy-cycle
    lengths, recording lengths and condition blocks, and the feature version it was read
    with."""
    from server.phm.features import FEATURE_VERSION
    from sim_worker.campaign import SCALES

    cfg = SCALES[DESIGN_SCALE]["design"]
    cycles = cfg.healthy_flights
    return {"kind": "design", "scale": DESIGN_SCALE, "seed": DESIGN_SEED,
            "healthy_cycle_flights": list(cycles) if isinstance(cycles, tuple) else [cycles] * 2,
            "recordings_s": list(cfg.recordings_s) or [cfg.duration_s],
            "condition_blocks": cfg.condition_blocks, "feature_version": FEATURE_VERSION}


def demo_model_document(payload: dict[str, Any], report: dict[str, Any]) -> dict[str, Any]:
    doc = trained_model_document(FORMAT, design_record(), TRAINING_SEED, payload, report)
    doc["leave_one_aircraft_out_healthy_rate"] = doc["training"]["detector"][
        "design_false_alarms"]
    return doc


def write_demo_model(out: str | Path, *, campaign: str | Path | None = None,
                     jobs: int | None = None) -> dict[str, Any]:
    """Stream the ``DESIGN_SCALE`` design campaign of ``DESIGN_SEED`` (or read ``campaign``,
    which must be that campaign), train on it with ``TRAINING_SEED`` and write the document to
    ``out``."""
    from server.campaigns import FeatureSink, train_from_directory
    from sim_worker import run_campaign

    with tempfile.TemporaryDirectory(prefix="hmsm-demo-design-") as tmp:
        design = Path(campaign) if campaign is not None else Path(tmp) / "design"
        if not (design / "manifest.json").exists():
            run_campaign("design", design, seed=DESIGN_SEED, scale=DESIGN_SCALE, workers=jobs,
                         progress=True, sink=FeatureSink())
        check_design(json.loads((design / "manifest.json").read_text()), design)
        model, report = train_from_directory(design, seed=TRAINING_SEED, jobs=jobs)
    doc = demo_model_document(model.to_dict(), report)
    Path(out).write_text(json.dumps(doc, sort_keys=True, separators=(",", ":")) + "\n")
    return doc


def check_design(manifest: dict[str, Any], where: object) -> None:
    """A ValueError unless ``manifest`` is the shipped model's default design campaign."""
    if (manifest.get("kind"), manifest.get("seed"), manifest.get("scale"),
            manifest.get("noise_scale"), manifest.get("sensor_faults") or [],
            manifest.get("bases")) != ("design", DESIGN_SEED, DESIGN_SCALE, 1.0, [], None):
        raise ValueError(f"{where} is not the default {DESIGN_SCALE} design campaign of seed "
                         f"{DESIGN_SEED}")


def load_demo_model() -> dict[str, Any]:
    """The shipped document (ValueError if it is not one)."""
    text = resources.files("server").joinpath("data/demo_model.json").read_text()
    doc = json.loads(text)
    if doc.get("format") != FORMAT:
        raise ValueError(f"server/data/demo_model.json: expected format {FORMAT!r}")
    return doc
