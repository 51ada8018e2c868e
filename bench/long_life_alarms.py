"""False alarms over long healthy lives, from a streamed campaign's stored features.

Two steps, so that detector variants are scored in seconds without simulating again::

    # 1. the residuals the detector sees, per pattern and flight (baseline + sensor judgement)
    python bench/long_life_alarms.py extract CAMPAIGN_DIR MODEL_JSON OUT.npz
    # 2. the detector of MODEL_JSON (or a variant) run over them: alarms, by unit, feature,
    #    season and reference age
    python bench/long_life_alarms.py score OUT.npz MODEL_JSON [--json REPORT.json]

``extract`` keeps, per flight: the standardised residuals ``z`` of the 20 aircraft features
after the sensor judgement, its extra variance, its evidence weights, each position's
operating conditions and the take-off time. ``score`` replays
:func:`server.phm.detection.update_units` per pattern (the chain's own detection path, without
classification or prognosis, which an alarm does not need).
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from server.campaigns import load_campaign  # noqa: E402
from server.phm.chain.model import PhmModel, read_model_document  # noqa: E402
from server.phm.detection import FaultDetector, new_states, update_units  # noqa: E402
from server.phm.features import AIRCRAFT_FEATURES, CONDITION_NAMES  # noqa: E402
from server.phm.metrics import event_rate  # noqa: E402
from server.vocabulary import POSITIONS  # noqa: E402


def _model(path: str) -> PhmModel:
    return read_model_document(json.loads(Path(path).read_text()))


def extract(campaign_dir: str, model_json: str, out: str) -> None:
    model = _model(model_json)
    camp = load_campaign(campaign_dir)
    arrays: dict[str, Any] = {}
    meta = []
    for p in camp.patterns:
        z = np.full((len(p.flights), len(AIRCRAFT_FEATURES)), np.nan)
        extra = np.zeros_like(z)
        evidence = model.baseline.evidence_matrix([r.features for r in p.flights])
        cond = np.full((len(p.flights), len(POSITIONS), len(CONDITION_NAMES)), np.nan)
        for i, r in enumerate(p.flights):
            zz = model.baseline.zscores(r.features)
            if model.sensors is not None and r.features.quality:
                j = model.sensors.judge(r.features.quality, zz,
                                        model.baseline.evidence_weights(r.features))
                zz = j.z
                for k, v in j.extra_variance.items():
                    extra[i, AIRCRAFT_FEATURES.index(k)] = v
            z[i] = [zz[n] for n in AIRCRAFT_FEATURES]
            for a, pos in enumerate(POSITIONS):
                cond[i, a] = [r.features.conditions[pos].get(c, np.nan) for c in CONDITION_NAMES]
        arrays[f"{p.id}/z"] = z
        arrays[f"{p.id}/extra"] = extra
        arrays[f"{p.id}/evidence"] = evidence
        arrays[f"{p.id}/cond"] = cond
        arrays[f"{p.id}/index"] = np.array([r.index for r in p.flights])
        arrays[f"{p.id}/day"] = np.array([r.started_at.timetuple().tm_yday - 1
                                          if r.started_at else -1 for r in p.flights])
        meta.append({"id": p.id, "aircraft": p.aircraft, "base": p.base, "mode": p.mode,
                     "position": p.position, "onset": p.onset_flight})
    arrays["meta"] = np.array(json.dumps(meta))
    np.savez_compressed(out, **arrays)
    print(f"{len(meta)} patterns, {sum(len(m) for k, m in arrays.items() if k.endswith('/z'))}"
          f" flights -> {out}")


def load(path: str) -> tuple[list[dict[str, Any]], dict[str, np.ndarray]]:
    data = np.load(path)
    return json.loads(str(data["meta"])), {k: data[k] for k in data.files if k != "meta"}


def replay(detector: FaultDetector, meta: dict[str, Any], arr: dict[str, np.ndarray]
           ) -> list[dict[str, Any]]:
    """New alarms of every unit over one pattern (healthy units only)."""
    pid = meta["id"]
    z, extra, day = arr[f"{pid}/z"], arr[f"{pid}/extra"], arr[f"{pid}/day"]
    weights = arr.get(f"{pid}/evidence", np.ones_like(z))
    idx = arr[f"{pid}/index"]
    states = new_states(detector, POSITIONS)
    alarms = []
    for i in range(z.shape[0]):
        zd = {n: float(z[i, k]) for k, n in enumerate(AIRCRAFT_FEATURES)}
        ev = {n: float(extra[i, k]) for k, n in enumerate(AIRCRAFT_FEATURES) if extra[i, k]}
        wd = {n: float(weights[i, k]) for k, n in enumerate(AIRCRAFT_FEATURES)}
        for pos, res in update_units(detector, states, zd, ev, wd).items():
            if res.new_alarm:
                alarms.append({"pattern": pid, "aircraft": meta["aircraft"],
                               "base": meta["base"], "unit": pos, "flight": int(idx[i]),
                               "day": int(day[i]), "features": res.alarm_features})
    return alarms


def score(npz: str, model_json: str, detector: FaultDetector | None = None) -> dict[str, Any]:
    metas, arr = load(npz)
    det = detector or _model(model_json).detector
    alarms: list[dict[str, Any]] = []
    flights = 0
    for m in metas:
        if m["mode"] != "healthy":
            continue
        flights += int(arr[f"{m['id']}/z"].shape[0])
        alarms += replay(det, m, arr)
    return {"patterns": sum(m["mode"] == "healthy" for m in metas), "flights": flights,
            **event_rate(len(alarms), flights * len(POSITIONS)),
            "patterns_alarmed": len({a["pattern"] for a in alarms}),
            "design_rate": det.false_alarm_rate,
            "by_unit": dict(Counter(a["unit"] for a in alarms)),
            "by_feature": dict(Counter(f.split(".")[1] for a in alarms for f in a["features"])),
            "list": alarms}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    ex = sub.add_parser("extract")
    ex.add_argument("campaign")
    ex.add_argument("model")
    ex.add_argument("out")
    sc = sub.add_parser("score")
    sc.add_argument("npz")
    sc.add_argument("model")
    sc.add_argument("--json", default=None)
    args = ap.parse_args(argv)
    if args.cmd == "extract":
        extract(args.campaign, args.model, args.out)
        return 0
    rep = score(args.npz, args.model)
    text = json.dumps(rep, indent=1)
    if args.json:
        Path(args.json).write_text(text)
    short = {k: v for k, v in rep.items() if k != "list"}
    print(json.dumps(short, indent=1))
    for a in rep["list"]:
        print(a)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
