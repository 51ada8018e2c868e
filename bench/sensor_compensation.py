"""What the sensor compensation does to healthy flights: per generic feature, the residuals of a
campaign's healthy patterns as the baseline gives them (raw), after the sensor model's bias
correction (judged), the added variance it assigns, and the judged residuals over their
assumed scatter ``sqrt(1 + added)``: about 1 where the compensation matches the noise, below
1 where it widens more than the noise does (and hides faults).

Usage: ``python bench/sensor_compensation.py CAMPAIGN_DIR MODEL_JSON``
"""

from __future__ import annotations

import argparse
import json
import math

import numpy as np

from server.campaigns import load_campaign
from server.phm.chain import read_model_document


def rows_by_feature(campaign: str, model_json: str) -> dict[str, np.ndarray]:
    """generic feature -> (n, 4): raw residual, judged residual, added variance, judged over
    its assumed scatter, one row per valid value of a healthy pattern's flight."""
    camp = load_campaign(campaign)
    with open(model_json) as fh:
        model = read_model_document(json.load(fh))
    acc: dict[str, list[tuple[float, float, float, float]]] = {}
    for pat in camp.patterns:
        if pat.mode != "healthy":
            continue
        for rec in pat.flights:
            f = rec.features
            z = model.baseline.zscores(f)
            judged = (model.sensors.judge(f.quality, z, model.baseline.evidence_weights(f))
                      if model.sensors is not None and f.quality else None)
            for name, v in z.items():
                if not math.isfinite(v):
                    continue
                zc = judged.z.get(name, v) if judged else v
                extra = judged.extra_variance.get(name, 0.0) if judged else 0.0
                acc.setdefault(name.split(".", 1)[1], []).append(
                    (v, zc, extra, zc / math.sqrt(1.0 + extra)))
    return {g: np.array(r) for g, r in sorted(acc.items())}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("campaign")
    ap.add_argument("model_json")
    args = ap.parse_args()
    print("| feature | values | raw mean / sd | judged mean / sd | added variance | "
          "judged / assumed scatter: sd, q99 |")
    print("|---|---|---|---|---|---|")
    for g, r in rows_by_feature(args.campaign, args.model_json).items():
        print(f"| {g} | {len(r):,} | {r[:, 0].mean():+.2f} / {r[:, 0].std():.2f} | "
              f"{r[:, 1].mean():+.2f} / {r[:, 1].std():.2f} | {r[:, 2].mean():.2f} | "
              f"{r[:, 3].std():.2f}, {np.quantile(r[:, 3], 0.99):.2f} |")


if __name__ == "__main__":
    main()
