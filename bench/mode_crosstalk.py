"""The design's cross-talk limits at each quantile of a grid, for choosing the quantile.

A second mode joins the modes present when its own feature, pooled since the alarm, is beyond
the leading mode's cross-talk: a quantile of that feature over the design's single faults of
the leading mode (:mod:`server.phm.classification.crosstalk`). This fits the limits on a
design campaign's classifier rows (the model's fleet reference and detector, as training does)
at every quantile of ``--quantiles`` and writes them; ``bench/mode_sets.py --crosstalk`` scores
each on other design seeds' evaluations.

The alternatives measured against the service's fit (docs/TUNING.md, ``CROSSTALK``):
``--flat`` (one limit per pair, not following the leading mode's own feature), ``--milder Q``
(the floor at the leader's quantile Q instead of ``MILDER``; ``--milder none``: no floor),
``--all-pairs`` (limits between every two progressive modes, not only those sharing a signal
path) and ``--pooled`` (the design's rows pooled per pattern as the chain pools its flights,
``CHAIN.class_evidence_decay``, instead of flight by flight).

    python bench/mode_crosstalk.py DESIGN_DIR --out CT.json [--model-json M.json]
        [--quantiles 0.9,0.95,...] [--flat | --milder Q] [--all-pairs] [--pooled]
"""

from __future__ import annotations

import argparse
import itertools
import json
from pathlib import Path

import numpy as np
from scipy.signal import lfilter

from server.campaigns import load_campaign
from server.demo_model import load_demo_model
from server.phm.chain import CHAIN, PhmModel, read_model_document
from server.phm.classification.crosstalk import MILDER, fit_crosstalk
from server.phm.prognosis import PrognoserConfig
from server.phm.training import training_rows
from server.vocabulary import PROGRESSIVE, SHARED_SIGNAL_PATH

QUANTILES = (0.9, 0.95, 0.98, 0.99, 0.995, 0.999, 1.0)


def pooled_means(X: np.ndarray, groups: np.ndarray, decay: float) -> np.ndarray:
    """Each row's decayed mean over its group's rows so far (a group's rows contiguous, in
    flight order): the chain's pooling, applied to the design's rendered flights."""
    out = np.empty_like(X, dtype=np.float64)
    starts = np.flatnonzero(np.r_[True, groups[1:] != groups[:-1]])
    for s, e in zip(starts, np.r_[starts[1:], len(groups)], strict=True):
        num = lfilter([1.0], [1.0, -decay], np.nan_to_num(X[s:e]), axis=0)
        out[s:e] = num / lfilter([1.0], [1.0, -decay], np.ones(e - s))[:, np.newaxis]
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("design")
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--model-json", type=Path,
                    help="the model whose reference and detector make the rows "
                         "(default: the shipped one)")
    ap.add_argument("--quantiles", default=",".join(map(str, QUANTILES)))
    ap.add_argument("--all-pairs", action="store_true")
    ap.add_argument("--pooled", action="store_true")
    ap.add_argument("--flat", action="store_true")
    ap.add_argument("--milder", default=str(MILDER))
    args = ap.parse_args()
    doc = (json.loads(args.model_json.read_text()) if args.model_json
           else load_demo_model()["payload"])
    model = read_model_document(doc)
    bare = PhmModel(model.baseline, model.detector, None, {}, PrognoserConfig())
    rows = training_rows(load_campaign(args.design, jobs=2), bare)
    X = (pooled_means(rows["X"], rows["groups"], CHAIN.class_evidence_decay) if args.pooled
         else rows["X"])
    pairs = (tuple(itertools.combinations(PROGRESSIVE, 2)) if args.all_pairs
             else SHARED_SIGNAL_PATH)
    milder = None if args.milder == "none" else float(args.milder)
    fits = {q: fit_crosstalk(X, rows["y"], quantile=float(q), pairs=pairs,
                             conditional=not args.flat, milder=milder).to_dict()
            for q in args.quantiles.split(",")}
    args.out.write_text(json.dumps({"design": str(args.design), "rows": len(rows["y"]),
                                    "pooled": args.pooled, "all_pairs": args.all_pairs,
                                    "flat": args.flat, "milder": milder, "fits": fits},
                                   indent=1) + "\n")
    for q, f in fits.items():
        print(q, {lead: {m: f"{t['at']:.2f} + {t['slope']:.2f} x" for m, t in row.items()}
                  for lead, row in f["limits"].items()})


if __name__ == "__main__":
    main()
