"""Healthy aircraft flown under test-station conditions or a sensor injection, every flight
analysed by the shipped model (server/data/demo_model.json) as the service analyses it: how
many actuator alarms, sensor findings and set-aside features.

    python bench/station_conditions.py --ambient 15 --load-scale 1.5 --flights 50 \\
        --out conditions.json                       # 3 aircraft, one per base
    python bench/station_conditions.py --sensor WT.lvdt:noise=3 --flights 10 --out lvdt.json
    python bench/station_conditions.py --sensor WT.current:stuck=0 --flights 5 --out stuck.json

Each aircraft flies ``--lead`` flights as drawn (its detector learns its offsets from them,
as a unit installed before the test would), then ``--flights`` under the condition, flown as
``sim-worker run`` flies them (sim_worker/conditions.py, sim_worker/sensors.py).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from server.demo_model import load_demo_model  # noqa: E402
from server.phm.chain import analyze_flight, read_model_document  # noqa: E402
from server.phm.recording import log_features  # noqa: E402
from server.vocabulary import POSITIONS  # noqa: E402
from sim_worker.conditions import NO_CONDITIONS, Conditions  # noqa: E402
from sim_worker.faults import healthy  # noqa: E402
from sim_worker.flight import flight_start, simulate_flight  # noqa: E402
from sim_worker.sensors import SensorInjection, degrade  # noqa: E402
from sim_worker.service import fleet_plan  # noqa: E402

#: one aircraft of each base of the ten-aircraft fleet plan: Turin, Vancouver, Abu Dhabi
DEFAULT_AIRCRAFT = (0, 4, 7)


def parse_sensor(text: str) -> SensorInjection:
    """``POS.SENSOR:KIND=VALUE``, e.g. ``WT.lvdt:noise=3``."""
    where, what = text.split(":")
    position, sensor = where.split(".")
    kind, value = what.split("=")
    return SensorInjection(0, position, sensor, kind, float(value), started=0)


def _model_document(path: str | None) -> dict[str, Any]:
    """The model document at ``path`` (``hmsm train --out`` or demo-model shape), default the
    shipped one."""
    return load_demo_model() if path is None else json.loads(Path(path).read_text())


def fly(index: int, conditions: Conditions, sensor: SensorInjection | None, seed: int,
        lead: int, flights: int, duration_s: float, model_path: str | None = None
        ) -> dict[str, Any]:
    """One aircraft's lead and test flights, each analysed; what the chain said."""
    model = read_model_document(_model_document(model_path))
    aircraft = fleet_plan(10, seed)[index]
    health = {p: model.new_health(p) for p in POSITIONS}
    rows = []
    for n in range(1, lead + flights + 1):
        under = n > lead
        flown = degrade(aircraft, [sensor], n) if under and sensor is not None else aircraft
        log, summary = simulate_flight(
            flown, healthy(), n, np.random.default_rng([seed, 13, index, n]),
            started_at=flight_start(n), duration_s=duration_s,
            conditions=conditions if under else NO_CONDITIONS)
        out = analyze_flight(model, log_features(log, ground_temp_c=summary.ground_temp_c),
                             health, seed=index, started_at=flight_start(n),
                             base=aircraft.base)
        rows.append({"flight": n, "under": under, "ground_temp_c": summary.ground_temp_c,
                     **{p: {"alarm": o.alarm, "mode": o.fault_mode,
                            "confidence": round(float(o.max_confidence), 4),
                            "z_top": _largest(o.z),
                            "findings": sorted({f["channel"] for f in o.sensor_findings}),
                            "set_aside": o.set_aside,
                            "outside_design": [
                                {"condition": x["condition"], "value": round(x["value"], 4),
                                 "range": [round(x["low"], 4), round(x["high"], 4)]}
                                for x in o.outside_design],
                            "winding_mean_c": summary.actuators[p].winding_mean_c,
                            "current_rms_a": summary.actuators[p].current_rms_a}
                        for p, o in out.items()}})
    return {"aircraft": aircraft.tail, "base": aircraft.base, "flights": rows}


def _largest(z: dict[str, float]) -> list[Any]:
    """The feature with the largest finite |z| of the flight, and its z."""
    finite = [(k, v) for k, v in z.items() if v is not None and np.isfinite(v)]
    if not finite:
        return [None, None]
    name, value = max(finite, key=lambda kv: abs(kv[1]))
    return [name, round(float(value), 2)]


def summarise(runs: list[dict[str, Any]]) -> dict[str, Any]:
    """Per aircraft and position: flights under test with an alarm, with a finding, with
    features set aside; the first of each; the mean winding temperature and current before
    and under the condition."""
    out: dict[str, Any] = {}
    for run in runs:
        for p in POSITIONS:
            lead = [r[p] for r in run["flights"] if not r["under"]]
            test = [(r["flight"], r[p]) for r in run["flights"] if r["under"]]
            out[f"{run['aircraft']} {p}"] = {
                "alarm_flights": sum(o["alarm"] for _, o in test),
                "lead_alarm_flights": sum(o["alarm"] for o in lead),
                "first_alarm": next((n for n, o in test if o["alarm"]), None),
                "modes": sorted({o["mode"] for _, o in test if o["mode"]}),
                "finding_flights": sum(bool(o["findings"]) for _, o in test),
                "first_finding": next((n for n, o in test if o["findings"]), None),
                "channels": sorted({c for _, o in test for c in o["findings"]}),
                "set_aside_flights": sum(bool(o["set_aside"]) for _, o in test),
                "set_aside": sorted({f for _, o in test for f in o["set_aside"]}),
                "outside_design": sorted({x["condition"] for _, o in test
                                          for x in o.get("outside_design", ())}),
                "winding_c": [round(float(np.mean([o["winding_mean_c"] for o in lead])), 2),
                              round(float(np.mean([o["winding_mean_c"] for _, o in test])), 2)],
                "current_rms_a": [round(float(np.mean([o["current_rms_a"] for o in lead])), 3),
                                  round(float(np.mean([o["current_rms_a"] for _, o in test])),
                                        3)]}
    return out


def _job(args: tuple[Any, ...]) -> dict[str, Any]:
    return fly(*args)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--ambient", type=float, default=0.0, help="ambient offset [K]")
    parser.add_argument("--load-scale", type=float, default=1.0)
    parser.add_argument("--load-offset", type=float, default=0.0, help="[N]")
    parser.add_argument("--command-scale", type=float, default=1.0)
    parser.add_argument("--base", default=None)
    parser.add_argument("--sensor", default=None, help="POS.SENSOR:KIND=VALUE")
    parser.add_argument("--aircraft", default=",".join(map(str, DEFAULT_AIRCRAFT)),
                        help="indices into the ten-aircraft fleet plan")
    parser.add_argument("--flights", type=int, default=50, help="flights under test")
    parser.add_argument("--lead", type=int, default=10, help="flights as drawn first")
    parser.add_argument("--duration", type=float, default=60.0, help="recording length [s]")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--model", default=None,
                        help="model document (default: the shipped server/data/demo_model.json)")
    parser.add_argument("--out", required=True)
    args = parser.parse_args()
    conditions = Conditions(ambient_offset_k=args.ambient, load_scale=args.load_scale,
                            load_offset_n=args.load_offset, command_scale=args.command_scale,
                            base=args.base)
    sensor = parse_sensor(args.sensor) if args.sensor else None
    jobs = [(int(i), conditions, sensor, args.seed, args.lead, args.flights, args.duration,
             args.model) for i in args.aircraft.split(",")]
    start = time.monotonic()
    with ProcessPoolExecutor(args.workers) as pool:
        runs = list(pool.map(_job, jobs))
    summary = summarise(runs)
    Path(args.out).write_text(json.dumps({"settings": vars(args), "summary": summary,
                                          "seconds": round(time.monotonic() - start),
                                          "runs": runs}, indent=1) + "\n")
    for key, s in summary.items():
        print(key, json.dumps(s))
    return 0


if __name__ == "__main__":
    sys.exit(main())
