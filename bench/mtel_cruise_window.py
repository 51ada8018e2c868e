"""F_MTEL under an ambient offset: the friction ratio of ``SIM01``'s drives (fleet seed 0) on
flights 11-16 (60 s), flown as ``sim-worker run`` flies them with each offset, features as the
service computes them. ``python bench/mtel_cruise_window.py`` (about 1 min on 2 cores)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from server.phm.recording import log_features  # noqa: E402
from sim_worker.conditions import Conditions  # noqa: E402
from sim_worker.faults import healthy  # noqa: E402
from sim_worker.flight import flight_start, simulate_flight  # noqa: E402
from sim_worker.service import fleet_plan  # noqa: E402

FEATURES = ("WT.F_MTEL", "WL1.F_MTEL", "WL2.F_MTEL")


def main() -> int:
    aircraft = fleet_plan(10, 0)[0]
    print("offset [K]", " ".join(FEATURES), "per flight 11-16")
    for offset in (0.0, 2.0, 5.0, 15.0, -15.0):
        row = []
        for n in range(11, 17):
            log, summary = simulate_flight(
                aircraft, healthy(), n, np.random.default_rng([0, 13, 0, n]),
                started_at=flight_start(n), duration_s=60.0,
                conditions=Conditions(ambient_offset_k=offset))
            values = log_features(log, ground_temp_c=summary.ground_temp_c).values()
            row.append(tuple(round(float(values[f]), 4) for f in FEATURES))
        print(f"{offset:+.0f}", row)
    return 0


if __name__ == "__main__":
    sys.exit(main())
