"""The campaign's fast path against the 12 kHz model on the sliding work that wears a winglet
drive, per role, on an active-standby tab.

Aircraft I-TEST01 (the sim tests' aircraft), a wear fault on WL1 at several severities, 8
flights of 60 s (4 with WL1 active, 4 standby): summed rendered over summed estimated
(``estimate_summary``) work of WL1, per role and both roles together. About 20 s on one core.

Usage: ``python bench/fast_path_agreement.py``
"""

from __future__ import annotations

import numpy as np

from sim_worker.faults import THRESHOLDS, FaultState
from sim_worker.fleet import WingletMode, active_channels, build_aircraft
from sim_worker.flight import estimate_summary, simulate_flight

FIELDS = {"REWEAR": "work_rod_end_n_m", "MTWEAR": "work_screw_n_m"}


def ratios(mode: str, severity_norm: float) -> dict[str, float]:
    aircraft = build_aircraft("I-TEST01", "Turin", seed=12345)
    winglet = WingletMode.ACTIVE_STANDBY
    thr = THRESHOLDS[mode]
    fault = FaultState(mode, "WL1", severity_norm * thr, thr)
    sums = {"active": np.zeros(2), "standby": np.zeros(2)}
    for n in range(8):
        _, rendered = simulate_flight(aircraft, fault, n, np.random.default_rng([2, n]),
                                      duration_s=60.0, winglet_mode=winglet)
        estimated = estimate_summary(aircraft, n, np.random.default_rng([2, n]), duration_s=60.0,
                                     winglet_mode=winglet)
        role = "active" if "WL1" in active_channels(winglet, n) else "standby"
        sums[role] += [getattr(rendered.actuators["WL1"], FIELDS[mode]),
                       getattr(estimated.actuators["WL1"], FIELDS[mode])]
    both = sums["active"] + sums["standby"]
    return {"active": sums["active"][0] / sums["active"][1],
            "standby": sums["standby"][0] / sums["standby"][1], "both": both[0] / both[1]}


def main() -> None:
    print("| fault on WL1 | s_n | active | standby | both roles |")
    print("|---|---|---|---|---|")
    for mode in FIELDS:
        for sn in (0.0, 0.5, 1.0):
            r = ratios(mode, sn)
            print(f"| {mode} | {sn:g} | {r['active']:.2f} | {r['standby']:.2f} | {r['both']:.2f} |")


if __name__ == "__main__":
    main()
