"""The committed protocol models (``docs/results/protocol_model.json``, the headline's;
``protocol_long_design_model.json``, trained on the design with long healthy cycles) stay
readable by the chain as it is: ``hmsm protocol --model-json`` with one scores the
verification alone."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from server.evaluation.protocol import MODEL_FORMAT
from server.phm.chain import read_model_document

RESULTS = Path(__file__).resolve().parents[2] / "docs" / "results"


@pytest.mark.parametrize("name", ["protocol_model.json", "protocol_long_design_model.json"])
def test_the_committed_protocol_model_is_read_by_the_chain(name: str) -> None:
    doc = json.loads((RESULTS / name).read_text())
    assert doc["format"] == MODEL_FORMAT
    assert doc["design"] == {"kind": "design", "scale": "protocol", "seed": 1}
    model = read_model_document(doc)
    assert set(model.measurement) >= {"TTS", "DMD", "MTEL", "MTWEAR", "REWEAR"}


def test_a_model_file_that_cannot_be_read_is_refused_before_any_simulation(
        tmp_path: Path) -> None:
    import argparse

    from server.config import load_settings
    from server.evaluation.protocol import add_protocol_arguments, run_protocol

    bad = tmp_path / "model.json"
    bad.write_text('{"format": "something else"}')
    for path in (bad, tmp_path / "missing.json"):
        args = add_protocol_arguments(argparse.ArgumentParser()).parse_args(
            ["--out", str(tmp_path / "run"), "--scale", "ci", "--model-json", str(path)])
        with pytest.raises(ValueError, match="not a model the chain reads"):
            run_protocol(args, load_settings())
        assert not (tmp_path / "run" / "verification").exists()
