"""Does the bank's leading hypothesis name the fault's true speed band, and would the RLS's
own rate estimate name it more often?

For every scored prediction of an ``hmsm evaluate`` output (10 per pattern from the first
alarm), the true band is the pattern's fault-to-failure span against the bank's hypotheses'
spans (fast below 100 flights, medium below 300, slow beyond); the bank's lead is the prediction's
``hypothesis``; the rate's band is the hypothesis under whose prior (normal, its rate and sd)
the filter's rate estimate (``rate_ratio`` times the prior centre of the prognoser that ran,
``MeasurementSpec.config_for`` its unit) is most likely. Counts per mode, as JSON.

    python bench/bank_lead.py --model server/data/demo_model.json EVAL_DIR [EVAL_DIR ...]
"""

from __future__ import annotations

import argparse
import json
import math
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Any

from server.phm.chain.model import read_model_document
from server.phm.prognosis.config import PrognoserConfig
from server.phm.prognosis.hypotheses import RateHypothesis
from server.vocabulary import PROGRESSIVE


def true_band(span: float, hypotheses: tuple[RateHypothesis, ...]) -> str:
    """The hypothesis whose spans hold ``span`` (the first below them, the last beyond)."""
    return next((h.name for h in hypotheses if span < h.high_flights), hypotheses[-1].name)


def rate_band(rate: float, hypotheses: tuple[RateHypothesis, ...]) -> str:
    """The hypothesis whose normal prior gives ``rate`` the highest density."""
    return max(hypotheses, key=lambda h: -0.5 * ((rate - h.rate) / h.rate_std) ** 2
               - math.log(h.rate_std)).name


def count(evaluation: dict[str, Any], config_for: Callable[[str], PrognoserConfig | None],
          mode: str) -> Counter:
    picked = {p["id"]: {q["flight"] for q in p["predictions"]}
              for p in evaluation["prognosis"][mode].get("patterns", [])}
    c: Counter = Counter()
    for t in evaluation["patterns"]:
        config = config_for(t["position"])
        if t["mode"] != mode or t["failure"] is None or config is None:
            continue
        bank = config.rate_hypotheses
        band = true_band(float(t["failure"] - t["onset"]), bank)
        for f in t["flights"]:
            r = f.get("rul")
            if f["index"] not in picked.get(t["id"], ()) or not r or not r.get("hypothesis") \
                    or not r.get("rate_ratio"):
                continue
            rate = float(r["rate_ratio"]) * config.theta0[1]  # as the filter forms the ratio
            c["predictions"] += 1
            c["lead right"] += r["hypothesis"]["name"] == band
            c["rate right"] += rate_band(rate, bank) == band
    return c


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("evaluations", nargs="+", type=Path, help="hmsm evaluate --out dirs")
    ap.add_argument("--model", type=Path, required=True, help="the model they were run with")
    args = ap.parse_args()
    model = read_model_document(json.loads(args.model.read_text(encoding="utf-8")))
    out = {}
    for d in args.evaluations:
        ev = json.loads((d / "evaluation.json").read_text(encoding="utf-8"))
        out[str(d)] = {m: dict(count(ev, model.measurement[m].config_for, m))
                       for m in PROGRESSIVE if m in ev["prognosis"] and m in model.measurement}
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
