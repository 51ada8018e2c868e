"""The committed protocol model (``docs/results/protocol_model.json``) stays readable by the
chain as it is: ``hmsm protocol --model-json`` with it scores the verification alone."""

from __future__ import annotations

import json
from pathlib import Path

from server.evaluation.protocol import MODEL_FORMAT
from server.phm.chain import read_model_document

MODEL = Path(__file__).resolve().parents[2] / "docs" / "results" / "protocol_model.json"


def test_the_committed_protocol_model_is_read_by_the_chain() -> None:
    doc = json.loads(MODEL.read_text())
    assert doc["format"] == MODEL_FORMAT
    assert doc["design"] == {"kind": "design", "scale": "protocol", "seed": 1}
    model = read_model_document(doc)
    assert set(model.measurement) >= {"TTS", "DMD", "MTEL", "MTWEAR", "REWEAR"}
