"""Refit one hypothesis group of a calibrated model's RUL band layer on replays at the service's
cadence, keeping every other group as calibrated.

The calibration designs (``bench/rul_suite.py calibration-stream``) render every third flight
to keep the slow band's design affordable, but the service judges every flight: a filter fed
three times as many measurements narrows its bands, and margins learned on the sparse replays
leave the lower end too high. Measured on the fast band's own design (seed 4, 30-100 flights)
replayed at every flight with the shipped model, which was calibrated on its every-third-flight
replays: its 90 % bands held 0.79-0.89 of the truths and left the truth below them in 0.07-0.14
of the predictions (docs/TUNING.md, ``calibration cadence``).

Streaming the medium and slow bands' designs at every flight costs hours; the fast band, where
a life gives the filter the fewest measurements, costs 25 minutes. So this refits the named
group's margins, sizes and median shifts per mode from ``hmsm calibrate`` run on every-flight
replays (``--refit``), and keeps the other groups and the pooled margins of ``--model``:

    hmsm campaign --kind design --scale quick --seed 4 --span-range 30,100 --span-draw log \\
        --render-every 1 --patterns-per-mode 20 --out CAL_FAST
    hmsm evaluate --campaign CAL_FAST --model-json UNCALIBRATED.json --out CAL_FAST_EVAL
    hmsm calibrate --evaluation CAL_FAST_EVAL --model-json UNCALIBRATED.json --out REFIT.json
    python bench/calibration_cadence.py --model CALIBRATED.json --refit REFIT.json \\
        --group fast --out MODEL.json
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from server.phm.chain.model import _unwrap, read_model_document


def graft(model_doc: dict[str, Any], refit_doc: dict[str, Any], group: str,
          source: str) -> dict[str, Any]:
    """``model_doc`` with each mode's ``group`` taken from ``refit_doc``'s layer."""
    ours, theirs = _unwrap(model_doc)["measurement"], _unwrap(refit_doc)["measurement"]
    for mode, spec in ours.items():
        layer, refit = spec.get("band_calibration"), theirs.get(mode, {}).get("band_calibration")
        if layer is None or refit is None:
            raise SystemExit(f"{mode}: both models need a calibration layer")
        if layer.get("hypotheses") != refit.get("hypotheses") or group not in layer["hypotheses"]:
            raise SystemExit(f"{mode}: the layers' groups differ or lack {group!r}")
        g = layer["hypotheses"].index(group)
        for key in ("margins", "counts", "shifts"):
            layer[key][g] = refit[key][g]
        layer["notes"] = {**layer.get("notes", {}),
                          f"group {group}": f"refitted on every-flight replays: {source}"}
    read_model_document(model_doc)  # the document still reads
    return model_doc


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", type=Path, required=True, help="the calibrated model")
    ap.add_argument("--refit", type=Path, required=True,
                    help="hmsm calibrate's output on the every-flight replays")
    ap.add_argument("--group", default="fast", help="the hypothesis group to refit")
    ap.add_argument("--source", default="", help="what the replays were (kept in the notes)")
    ap.add_argument("--out", type=Path, required=True)
    args = ap.parse_args()
    doc = graft(json.loads(args.model.read_text(encoding="utf-8")),
                json.loads(args.refit.read_text(encoding="utf-8")), args.group,
                args.source or str(args.refit))
    args.out.write_text(json.dumps(doc, sort_keys=True, separators=(",", ":")) + "\n",
                        encoding="utf-8")


if __name__ == "__main__":
    main()
