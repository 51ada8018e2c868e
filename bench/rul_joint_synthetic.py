"""The particle filter's RUL bands on synthetic exponential lives at several fault speeds, per
filter variant: the RLS with its mixture prior, the joint state-parameter filter at two
severity random walks, and the joint filter with the online guard.

    python bench/rul_joint_synthetic.py [--seeds 6]      # about 2 min on one core

A life: dh/dk = f r0 (h + c) from h = 0.05 to 1 (c = 0.3, r0 = 0.0045: 290 flights at f = 1),
a log-normal scatter of 0.1 per flight, the feature h + N(0, 0.05^2). The filters' prior is
centred on r0; predictions every flight from 30 % of the life. Per variant and speed f: the
mean life, the share of predictions whose 50 % and 90 % bands hold the true RUL, and the
median relative error of the median RUL (mean over seeds).
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from server.phm.prognosis import (  # noqa: E402
    MeasurementModel,
    ParticleFilterPrognoser,
    PrognoserConfig,
)

C, R0, NOISE = 0.3, 0.0045, 0.05
RLS = PrognoserConfig(rate_basis="exponential", growth_offset=C, initial_theta=(0.0, R0),
                      initial_rate_std=0.35 * R0, rate_bounds=(R0 * 0.8 * 0.3 / 1.5,
                                                                 R0 * 0.8 * 16),
                      rls_forgetting=0.995, rate_prior_tail=0.2)
JOINT = replace(RLS, joint_rate=True, rate_prior_tail=0.0, rate_prior_log_std=1.0)
VARIANTS = {"rls (mixture prior)": RLS, "joint, walk 0.01": JOINT,
            "joint, walk 0.003": replace(JOINT, process_noise_std=0.003),
            "joint, walk 0.003, guard 10": replace(JOINT, process_noise_std=0.003,
                                                   guard_horizon=10)}


def run(config: PrognoserConfig, speed: float, seed: int) -> tuple[float, float, float, int]:
    rng = np.random.default_rng(seed)
    h = [0.05]
    while h[-1] < 1.0:
        h.append(h[-1] + speed * R0 * (h[-1] + C) * math.exp(0.1 * rng.standard_normal()))
    life = len(h) - 1
    model = MeasurementModel.identity(NOISE)
    pf = ParticleFilterPrognoser(config, model)
    state = pf.initial_state(config, model, seed)
    in50 = in90 = n = 0
    errors = []
    for k in range(life):
        state = pf.update(state, h[k] + NOISE * rng.standard_normal(), k)
        if k >= 0.3 * life:
            q = pf.predict(state).quantiles
            true = life - k
            n += 1
            in90 += q[0.05] <= true <= q[0.95]
            in50 += q[0.25] <= true <= q[0.75]
            errors.append((q[0.5] - true) / max(true, 1))
    return in50 / n, in90 / n, float(np.median(errors)), life


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seeds", type=int, default=6)
    args = parser.parse_args()
    print("| variant | speed | life [flights] | 50 % held | 90 % held | median rel. error |")
    print("|---|---|---|---|---|---|")
    for name, config in VARIANTS.items():
        for speed in (0.3, 1.0, 4.0):
            r = np.array([run(config, speed, s) for s in range(args.seeds)])
            print(f"| {name} | {speed:g} | {r[:, 3].mean():.0f} | {r[:, 0].mean():.2f} "
                  f"| {r[:, 1].mean():.2f} | {r[:, 2].mean():+.2f} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
