"""The design's cross-talk limits at each quantile of a grid, for choosing the quantile.

A second mode joins the modes present when its own feature, pooled since the alarm, is beyond
the leading mode's cross-talk: a quantile of that pooled feature over the design's single
faults of the leading mode (:mod:`server.phm.classification.crosstalk`). This fits the limits
on a design campaign's classifier rows (the model's fleet reference and detector, as training
does) at every quantile of ``--quantiles`` and writes them; ``bench/mode_sets.py --crosstalk``
scores each on other design seeds' evaluations.

    python bench/mode_crosstalk.py DESIGN_DIR --out CT.json [--model-json M.json]
        [--quantiles 0.9,0.95,...]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from server.campaigns import load_campaign
from server.demo_model import load_demo_model
from server.phm.chain import CHAIN, PhmModel, read_model_document
from server.phm.classification.crosstalk import fit_crosstalk
from server.phm.prognosis import PrognoserConfig
from server.phm.training import training_rows

QUANTILES = (0.9, 0.95, 0.98, 0.99, 0.995, 0.999, 1.0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("design")
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--model-json", type=Path,
                    help="the model whose reference and detector make the rows "
                         "(default: the shipped one)")
    ap.add_argument("--quantiles", default=",".join(map(str, QUANTILES)))
    args = ap.parse_args()
    doc = (json.loads(args.model_json.read_text()) if args.model_json
           else load_demo_model()["payload"])
    model = read_model_document(doc)
    bare = PhmModel(model.baseline, model.detector, None, {}, PrognoserConfig())
    rows = training_rows(load_campaign(args.design, jobs=2), bare)
    fits = {q: fit_crosstalk(rows["X"], rows["y"], rows["groups"],
                             decay=CHAIN.class_evidence_decay, quantile=float(q)).to_dict()
            for q in args.quantiles.split(",")}
    args.out.write_text(json.dumps({"design": str(args.design), "rows": len(rows["y"]),
                                    "fits": fits}, indent=1) + "\n")
    for q, f in fits.items():
        print(q, {lead: {m: round(t, 2) for m, t in row.items()}
                  for lead, row in f["limits"].items()})


if __name__ == "__main__":
    main()
