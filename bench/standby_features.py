"""The six motor features of each winglet drive in each role, on healthy active-standby flights.

Two aircraft, six 120 s flights each; per drive and flight its role (A active, S standby) and
every feature's value / valid steps. Shows why a standby's motor features are not read: the
leakage, imbalance and friction tests need a switching inverter, and the flux estimate from the
damping currents rests on a hundred-odd valid steps with a role offset (docs/FEATURES.md).
About 15 s on one core.

Usage: ``python bench/standby_features.py``
"""

from __future__ import annotations

import numpy as np

from server.phm.features import FeatureConfig, actuator_features
from server.vocabulary import SIGNALS, WINGLET_PAIR
from sim_worker.faults import healthy
from sim_worker.fleet import WingletMode, active_channels, build_aircraft
from sim_worker.flight import simulate_flight


def main() -> None:
    cfg = FeatureConfig()
    mode = WingletMode.ACTIVE_STANDBY
    for a in range(2):
        aircraft = build_aircraft(f"I-T{a}", "Turin", seed=100 + a)
        for n in range(6):
            log, _ = simulate_flight(aircraft, healthy(), n, np.random.default_rng([a, n]),
                                     duration_s=120.0, winglet_mode=mode)
            ch = {k: np.asarray(v, dtype=np.float64) for k, v in log.channels.items()}
            for p in WINGLET_PAIR:
                tracks, _ = actuator_features(
                    {s: ch[f"{p}.{s}"] for s in SIGNALS},
                    aero_gradient_n_per_m=float(cfg.aero_gradient_n_per_m[p]),
                    aero_bias_n=float(cfg.aero_bias_n[p]), t_amb_c=ch["T_amb"], config=cfg)
                role = "A" if p in active_channels(mode, n) else "S"
                cells = " ".join(f"{k}={t.summary().value:.4g}/{t.summary().n_valid}"
                                 for k, t in tracks.items())
                print(f"{aircraft.tail} flight {n} {p} {role} {cells}")


if __name__ == "__main__":
    main()
