"""The alarms a model's detector raises on its design's own healthy lives, listed, and the rate
split by flight kind (nominal or under the test station's conditions, recording length)::

    python bench/design_healthy_alarms.py DESIGN_DIR MODEL_JSON [--rates 3e-5,1.5e-5] [--json OUT]

DESIGN_DIR: the streamed ``shipped`` design of seed 1 (``hmsm campaign --kind design --scale
shipped --seed 1``), the one MODEL_JSON was trained on. The residuals are the training's
(leave-one-aircraft-out baselines, :func:`server.phm.detection_model.out_of_fold_residuals`);
for each stated rate the detector is fitted again on them with only ``false_alarm_rate``
changed, and
each aircraft's units are judged together as the chain judges them, each unit at risk until its
first alarm (the training's ``design_false_alarms``). A flight's kind comes from the campaign's
plan (``block_conditions``, ``recording_s``): the service itself is not told which flights ran
under the station's conditions.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import Counter
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from server.campaigns import load_campaign  # noqa: E402
from server.phm.chain.model import read_model_document  # noqa: E402
from server.phm.dataset import Campaign, is_healthy_flight  # noqa: E402
from server.phm.detection import FaultDetector, first_alarms  # noqa: E402
from server.phm.detection.config import unit_of  # noqa: E402
from server.phm.detection.sequences import judge_sequence  # noqa: E402
from server.phm.detection_model import out_of_fold_residuals  # noqa: E402
from server.phm.features import AIRCRAFT_FEATURES  # noqa: E402
from server.phm.metrics import event_rate  # noqa: E402
from sim_worker.campaign.planning import block_conditions, plan_campaign, recording_s  # noqa: E402
from sim_worker.campaign.scales import kind_config  # noqa: E402
from sim_worker.conditions import NO_CONDITIONS  # noqa: E402


def _healthy_sequences(camp: Campaign) -> list[tuple[str, str, list[Any]]]:
    """(aircraft, pattern id, healthy flight records), as training's ``healthy_flights``."""
    out = []
    for p in camp.patterns:
        recs = [r for r in p.flights if is_healthy_flight(p, r)]
        if recs:
            out.append((p.aircraft, p.id, recs))
    return out


def _score(det: FaultDetector, seqs: list[tuple[str, str, list[Any]]],
           oof: list[tuple[int, np.ndarray, np.ndarray]], kinds: dict[str, list[str]]
           ) -> dict[str, Any]:
    """The rate by flight kind and the alarms, each unit at risk until its first alarm
    (:func:`~server.phm.detection.first_alarms`, as the training's rate)."""
    names = [n for n in AIRCRAFT_FEATURES if n in det.feature_names_]
    cols = [AIRCRAFT_FEATURES.index(n) for n in names]
    at_risk: Counter[str] = Counter()
    hits: Counter[str] = Counter()
    alarms = []
    for h, z, ev in oof:
        _, pid, recs = seqs[h]
        first = first_alarms(det, z[:, cols], names, ev[:, cols])
        firing = None
        for unit, row in first.items():
            at_risk.update(kinds[pid][:len(recs) if row is None else row + 1])
            if row is None:
                continue
            hits[kinds[pid][row]] += 1
            if firing is None:  # which features: the judge again, only where a unit alarmed
                firing = judge_sequence(det, z[:, cols], names, ev[:, cols]).firing
            alarms.append({"pattern": pid, "unit": unit, "flight": recs[row].index,
                           "kind": kinds[pid][row],
                           "features": [n for k, n in enumerate(names)
                                        if unit_of(n) == unit and firing[row, k]]})
    return {"stated_rate": det.false_alarm_rate,
            **event_rate(sum(hits.values()), sum(at_risk.values())),
            "by_kind": {k: event_rate(hits[k], at_risk[k]) for k in sorted(at_risk)},
            "alarms": alarms}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("design")
    ap.add_argument("model")
    ap.add_argument("--rates", default="3e-5", help="stated rates, comma-separated")
    ap.add_argument("--json", default=None)
    args = ap.parse_args(argv)
    model = read_model_document(json.loads(Path(args.model).read_text()))
    camp = load_campaign(args.design)
    seqs = _healthy_sequences(camp)
    cfg = kind_config("shipped", "design")
    specs = {s.id: s for s in plan_campaign("design", camp.seed, "shipped")}

    def kind(pid: str, index: int) -> str:
        spec = specs[pid]
        station = block_conditions(cfg, spec, index) != NO_CONDITIONS
        return f"{'station' if station else 'nominal'}, {recording_s(cfg, spec, index):g} s"

    kinds = {pid: [kind(pid, r.index) for r in recs] for _, pid, recs in seqs}
    oof = out_of_fold_residuals([(a, [r.features for r in recs]) for a, _, recs in seqs],
                                model.baseline)
    rows = []
    for rate in (float(x) for x in args.rates.split(",")):
        det = FaultDetector.from_config(replace(model.detector.config, false_alarm_rate=rate))
        det.fit([z for _, z, _ in oof], AIRCRAFT_FEATURES, [e for _, _, e in oof])
        rows.append(_score(det, seqs, oof, kinds))
    report = {"design": args.design, "model": args.model, "rows": rows}
    if args.json:
        Path(args.json).write_text(json.dumps(report, indent=1) + "\n")
    print(json.dumps(report, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
