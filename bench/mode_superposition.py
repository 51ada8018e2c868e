"""Per-mode models taught with superposed pairs, against Platt's per-mode probabilities.

The shipped per-mode probability is Platt's sigmoid on the one-vs-rest SVM's decision value,
learned from single faults only: the SVM learned that a high ``F_TTS`` argues against DMD (a
TTS moves ``F_DMD`` too), so a DMD beside a TTS is hard to name. The alternative scored here: per
mode, a logistic regression on the design's single-fault rows plus synthetic two-mode rows (two
rows of different modes, their residuals added: ``c(e(x_a) + e(x_b))`` with ``e`` the inverse of
the classifier's ``sign(x) log(1 + |x|)`` compression, ``PAIRS`` per pair of modes). Both are
pooled over the flights since the alarm as the chain pools them (decayed mean of decision
values), on every unit-flight in alarm of a concurrent and a single-fault campaign replayed
with the shipped model; reported per threshold: unit-flights whose second mode was named (of
those carrying one beside the leader), unit-flights naming a mode not carried, and by pair.

    python bench/mode_superposition.py DESIGN_DIR CONCURRENT_DIR SINGLE_DIR [--pairs 60]
"""

from __future__ import annotations

import argparse
from collections import Counter
from collections.abc import Callable
from typing import Any

import numpy as np
from scipy.special import expit
from sklearn.linear_model import LogisticRegression

from server.campaigns import campaign_store, load_campaign, read_manifest
from server.demo_model import load_demo_model
from server.phm.chain import CHAIN, PhmModel, analyze_flight
from server.phm.chain.inputs import classifier_vector
from server.phm.prognosis import PrognoserConfig
from server.phm.training import training_rows
from server.vocabulary import POSITIONS

Record = dict[str, Any]
THRESHOLDS = (0.3, 0.5, 0.6, 0.8, 0.9)


def unit_flights(model: PhmModel, directory: str) -> list[Record]:
    """Every unit-flight in alarm: its classifier vector, leading mode and true modes."""
    camp = load_campaign(directory, jobs=1)
    manifest = read_manifest(campaign_store(directory))
    truth = {p["id"]: {int(f["index"]): [(x["position"], x["mode"])
                                          for x in f.get("faults") or []]
                       for f in p["flights"]} for p in manifest["patterns"]}
    out = []
    for p in camp.patterns:
        health = {pos: model.new_health(pos) for pos in POSITIONS}
        for r in p.flights:
            res = analyze_flight(model, r.features, health, seed=1, flight_index=r.index,
                                 started_at=r.started_at, base=p.base)
            here = truth.get(p.id, {}).get(r.index)
            if here is None:  # a single-fault pattern
                here = ([(p.position, p.mode)] if p.mode != "healthy"
                        and r.index >= (p.onset_flight or 0) else [])
            out += [{"unit": (p.id, pos), "lead": o.fault_mode,
                     "x": classifier_vector(health[pos].detection, pos),
                     "true": {m for q, m in here if q == pos}}
                    for pos, o in res.items() if o.alarm]
    return out


def superposed_model(model: PhmModel, design: str, pairs: int
                     ) -> Callable[[np.ndarray], np.ndarray]:
    """Per-mode logistic decision values, fitted on the design's rows plus superposed pairs."""
    clf = model.classifier
    assert clf is not None
    camp = load_campaign(design, jobs=2)
    rows = training_rows(camp, PhmModel(model.baseline, model.detector, None, {},
                                        PrognoserConfig()))
    classes = [str(c) for c in clf.classes_]
    X, yi = rows["X"], np.array([classes.index(str(v)) for v in rows["y"]])
    k = len(classes)
    rng = np.random.default_rng(0)
    xs, ys = [X], [np.eye(k)[yi]]
    for a in range(k):
        for b in range(a + 1, k):
            i = rng.choice(np.flatnonzero(yi == a), pairs)
            j = rng.choice(np.flatnonzero(yi == b), pairs)
            e = np.sign(X[i]) * np.expm1(np.abs(X[i])) + np.sign(X[j]) * np.expm1(np.abs(X[j]))
            xs.append(np.sign(e) * np.log1p(np.abs(e)))
            y = np.zeros((pairs, k))
            y[:, [a, b]] = 1.0
            ys.append(y)
    Z, Y = (np.vstack(xs) - clf.mean_) / clf.scale_, np.vstack(ys)
    fits = [LogisticRegression().fit(Z, Y[:, m]) for m in range(k)]
    W = np.array([f.coef_[0] for f in fits])
    icpt = np.array([f.intercept_[0] for f in fits])
    return lambda x: ((x - clf.mean_) / clf.scale_) @ W.T + icpt


def score(recs: list[Record], classes: list[str], decision: Callable[[np.ndarray], np.ndarray],
          proba: Callable[[np.ndarray], np.ndarray], t: float) -> dict[str, Any]:
    units: dict[Any, list[Record]] = {}
    for r in recs:
        units.setdefault(r["unit"], []).append(r)
    named, carried, wrong, n = Counter[Any](), Counter[Any](), 0, 0
    decay = CHAIN.class_evidence_decay
    for seq in units.values():
        acc, w = np.zeros(len(classes)), 0.0
        for r, d in zip(seq, decision(np.array([r["x"] for r in seq])), strict=True):
            acc, w = decay * acc + d, decay * w + 1.0
            q = proba((acc / w)[np.newaxis, :])[0]
            names = {r["lead"]} | {c for c, v in zip(classes, q, strict=True) if v >= t}
            n += 1
            wrong += any(m not in r["true"] for m in names - {r["lead"]})
            for m in r["true"] - {r["lead"]}:
                carried[(r["lead"], m)] += 1
                named[(r["lead"], m)] += m in names
    return {"threshold": t, "second_named": sum(named.values()),
            "second_carried": sum(carried.values()), "spurious": wrong, "unit_flights": n,
            "by_pair": {f"{a}->{b}": f"{named[(a, b)]}/{c}"
                        for (a, b), c in sorted(carried.items())}}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("design")
    ap.add_argument("concurrent")
    ap.add_argument("single")
    ap.add_argument("--pairs", type=int, default=60)
    args = ap.parse_args()
    model = PhmModel.from_dict(load_demo_model()["payload"])
    clf = model.classifier
    assert clf is not None
    classes = [str(c) for c in clf.classes_]
    con, single = unit_flights(model, args.concurrent), unit_flights(model, args.single)
    variants = {"platt": (clf.decision_function, clf.mode_proba_from_decision),
                "superposed": (superposed_model(model, args.design, args.pairs),
                               expit)}
    for name, (decision, proba) in variants.items():
        for t in THRESHOLDS:
            c = score(con, classes, decision, proba, t)
            s = score(single, classes, decision, proba, t)
            print(f"{name} {t:.1f}: second mode named {c['second_named']}/"
                  f"{c['second_carried']}, spurious concurrent {c['spurious']}/"
                  f"{c['unit_flights']}, single {s['spurious']}/{s['unit_flights']}; "
                  f"{c['by_pair']}")


if __name__ == "__main__":
    main()
