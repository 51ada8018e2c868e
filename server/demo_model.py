"""The model the demo starts with, shipped in the package (``server/data/demo_model.json``).

Training a model on the demo's first run means simulating a design campaign first: minutes on
two cores before the URL appears. The demo instead starts on a model trained by our own
commands on a seeded design campaign -- the quick design campaign of seed ``DESIGN_SEED``,
trained with seed ``TRAINING_SEED`` -- and ships the result. ``hmsm demo-model --out FILE``
regenerates it; the test suite trains the same campaign with the same seed and checks that the
shipped document is what that command produces (``tests/test_demo.py``).

The document: ``{"format": "ema-demo-model/1", "design": {...}, "training_seed": ...,
"payload": <ema-phm-model document>, "training": <training report>}``; the report is stored
without what depends on the machine (timings, the campaign's directory).
"""

from __future__ import annotations

import json
import tempfile
from importlib import resources
from pathlib import Path
from typing import Any

__all__ = ["DESIGN_SEED", "TRAINING_SEED", "FORMAT", "TRAINED_MODEL_FORMAT",
           "demo_model_document", "load_demo_model",
           "portable_report", "trained_model_document", "write_demo_model"]

DESIGN_SEED = 1
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


def demo_model_document(payload: dict[str, Any], report: dict[str, Any]) -> dict[str, Any]:
    return trained_model_document(
        FORMAT, {"kind": "design", "scale": "quick", "seed": DESIGN_SEED}, TRAINING_SEED,
        payload, report)


def write_demo_model(out: str | Path, *, campaign: str | Path | None = None,
                     jobs: int | None = None) -> dict[str, Any]:
    """Simulate the quick design campaign of ``DESIGN_SEED`` (or read ``campaign``, which must
    be that campaign), train on it with ``TRAINING_SEED`` and write the document to ``out``."""
    from server.campaigns import train_from_directory
    from sim_worker import run_campaign

    with tempfile.TemporaryDirectory(prefix="hmsm-demo-design-") as tmp:
        design = Path(campaign) if campaign is not None else Path(tmp) / "design"
        if not (design / "manifest.json").exists():
            run_campaign("design", design, seed=DESIGN_SEED, scale="quick", workers=jobs,
                         progress=True)
        manifest = json.loads((design / "manifest.json").read_text())
        if (manifest.get("kind"), manifest.get("seed"), manifest.get("scale"),
                manifest.get("noise_scale"), manifest.get("sensor_faults") or [],
                manifest.get("bases")) != ("design", DESIGN_SEED, "quick", 1.0, [], None):
            raise ValueError(f"{design} is not the default quick design campaign of seed "
                             f"{DESIGN_SEED}")
        model, report = train_from_directory(design, seed=TRAINING_SEED, jobs=jobs)
    doc = demo_model_document(model.to_dict(), report)
    Path(out).write_text(json.dumps(doc, sort_keys=True, separators=(",", ":")) + "\n")
    return doc


def load_demo_model() -> dict[str, Any]:
    """The shipped document (ValueError if it is not one)."""
    text = resources.files("server").joinpath("data/demo_model.json").read_text()
    doc = json.loads(text)
    if doc.get("format") != FORMAT:
        raise ValueError(f"server/data/demo_model.json: expected format {FORMAT!r}")
    return doc
