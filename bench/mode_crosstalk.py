"""How much of a second mode's own feature the leading mode's cross-talk explains.

A DMD beside a leading TTS is rarely named (docs/RESULTS.md, section 6): the one-vs-rest SVM
learned from single faults that a high ``F_TTS`` argues against DMD, because a TTS moves
``F_DMD`` too. This measures whether ``F_DMD`` itself still tells them apart: on every
unit-flight in alarm led by ``--lead`` (a concurrent and a single-fault design campaign,
replayed with the shipped model as :mod:`bench.mode_superposition` does), the second mode's own
feature in the classifier's input on flights that carry it against flights that do not (ROC
AUC), and how many carrying flights lie above the non-carrying flights' quantiles: a rule that
names the second mode when its own feature is beyond the leader's cross-talk.

    python bench/mode_crosstalk.py CONCURRENT_DIR SINGLE_DIR [--lead TTS --second DMD]
"""

from __future__ import annotations

import argparse

import numpy as np
from mode_superposition import unit_flights
from sklearn.metrics import roc_auc_score

from server.demo_model import load_demo_model
from server.phm.chain import PhmModel
from server.vocabulary import GENERIC_FEATURES, OWN_FEATURE


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("concurrent")
    ap.add_argument("single")
    ap.add_argument("--lead", default="TTS")
    ap.add_argument("--second", default="DMD")
    args = ap.parse_args()
    model = PhmModel.from_dict(load_demo_model()["payload"])
    recs = unit_flights(model, args.concurrent) + unit_flights(model, args.single)
    col = list(GENERIC_FEATURES).index(OWN_FEATURE[args.second])
    led = [r for r in recs if r["lead"] == args.lead]
    with_ = np.array([r["x"][col] for r in led if args.second in r["true"]])
    without = np.array([r["x"][col] for r in led if args.second not in r["true"]])
    labels = np.r_[np.ones(with_.size), np.zeros(without.size)]
    print(f"{args.lead}-led unit-flights: {with_.size} carrying {args.second}, "
          f"{without.size} not; ROC AUC of {OWN_FEATURE[args.second]}: "
          f"{roc_auc_score(labels, np.r_[with_, without]):.3f}")
    for q in (0.9, 0.95, 0.99):
        t = float(np.quantile(without, q))
        print(f"above the non-carrying flights' {100 * q:.0f} % quantile ({t:.2f}): "
              f"{int((with_ > t).sum())} of {with_.size}")


if __name__ == "__main__":
    main()
