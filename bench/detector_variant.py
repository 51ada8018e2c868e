"""A model with its detector refitted under other hyper-parameters, for choosing them on design
seeds without training the whole chain again::

    python bench/detector_variant.py DESIGN_DIR MODEL_JSON OUT_JSON --set surface_split_ratio=inf

The baselines, classifier, prognosis and sensor model are MODEL_JSON's; only the detector is
fitted again on DESIGN_DIR's healthy flights (the design MODEL_JSON was trained on) with
``--set`` applied to its configuration, and the design's leave-one-aircraft-out healthy rate
recomputed. The classifier keeps the rows the old detector's alarms gave it, so a variant is a
check of detection; the chosen setting is then trained in full (``hmsm demo-model``). Score the
variant with ``hmsm evaluate --model-json OUT_JSON`` or ``bench/long_life_alarms.py score``.
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import replace
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from server.campaigns import load_campaign  # noqa: E402
from server.phm.chain.model import read_model_document  # noqa: E402
from server.phm.detection import FaultDetector  # noqa: E402
from server.phm.detection_model import fit_detection  # noqa: E402


def _setting(text: str) -> tuple[str, Any]:
    name, _, value = text.partition("=")
    if not value:
        raise argparse.ArgumentTypeError(f"expected NAME=VALUE, got {text!r}")
    return name, json.loads(value) if value not in ("inf", "Infinity") else float("inf")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("design")
    parser.add_argument("model_json")
    parser.add_argument("out")
    parser.add_argument("--set", type=_setting, action="append", default=[],
                        metavar="NAME=VALUE", help="a DetectionConfig field, JSON value")
    parser.add_argument("--jobs", type=int, default=1)
    args = parser.parse_args()
    doc = json.loads(Path(args.model_json).read_text())
    model = read_model_document(doc)
    config = replace(model.detector.config, **dict(args.set))
    fitted = fit_detection(load_campaign(args.design, jobs=args.jobs),
                           detector=FaultDetector.from_config(config))
    payload = replace(model, detector=fitted.detector).to_dict()
    rate = fitted.design_false_alarms
    if "payload" in doc:
        doc["payload"] = payload
        doc.setdefault("training", {}).setdefault("detector", {})["design_false_alarms"] = rate
        if "leave_one_aircraft_out_healthy_rate" in doc:
            doc["leave_one_aircraft_out_healthy_rate"] = rate
    else:
        doc = payload
    Path(args.out).write_text(json.dumps(doc, sort_keys=True, separators=(",", ":")) + "\n")
    print(json.dumps({"set": dict(args.set), "design_false_alarms": rate}, default=str))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
