"""How much of a standby partner's grease ageing the active winglet drive's ``F_MTEL`` sees.

On the active-standby tab the active drive moves the standby's rod end, so the standby's screw
and motor are back-driven: their drag is part of the hinge work the active drive's friction
ratio measures. This bench gives one winglet drive an MTEL fault at normalised severities 0 to
1 and reads ``F_MTEL`` of both drives on the flights each is active (design-side aircraft, not
the verification's). The share ``k = dF_partner / dF_faulty`` is what a partner-drive alarm
rests on (docs/FEATURES.md, "Over a long life").

Usage: ``python bench/partner_drag.py [--flights N]`` (about 1 s a flight on one core).
"""

from __future__ import annotations

import argparse

import numpy as np

from server.phm.features import FeatureConfig, actuator_features
from server.vocabulary import SIGNALS, WINGLET_PAIR
from sim_worker.faults import THRESHOLDS, FaultState
from sim_worker.fleet import WingletMode, active_channels, build_aircraft
from sim_worker.flight import simulate_flight

SEVERITIES = (0.0, 0.5, 1.0)


def f_mtel(channels: dict[str, np.ndarray], position: str, cfg: FeatureConfig) -> float:
    tracks, _ = actuator_features(
        {s: channels[f"{position}.{s}"] for s in SIGNALS},
        aero_gradient_n_per_m=float(cfg.aero_gradient_n_per_m[position]),
        aero_bias_n=float(cfg.aero_bias_n[position]), t_amb_c=channels["T_amb"], config=cfg)
    return float(tracks["F_MTEL"].summary().value)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--flights", type=int, default=6, help="flights per severity (even count)")
    args = ap.parse_args()
    cfg = FeatureConfig()
    mode = WingletMode.ACTIVE_STANDBY
    aircraft = build_aircraft("I-PD1", "Turin", seed=301)
    faulty, partner = WINGLET_PAIR[1], WINGLET_PAIR[0]
    rows = {}
    for s_norm in SEVERITIES:
        fault = FaultState(mode="MTEL", position=faulty, severity=s_norm * THRESHOLDS["MTEL"],
                           threshold=THRESHOLDS["MTEL"])
        vals: dict[str, list[float]] = {faulty: [], partner: []}
        for n in range(args.flights):
            log, _ = simulate_flight(aircraft, fault, n, np.random.default_rng([7, n]),
                                     duration_s=120.0, winglet_mode=mode)
            ch = {k: np.asarray(v, dtype=np.float64) for k, v in log.channels.items()}
            (active,) = [p for p in WINGLET_PAIR if p in active_channels(mode, n)]
            vals[active].append(f_mtel(ch, active, cfg))
        rows[s_norm] = {p: (np.nanmean(v), np.nanstd(v), int(np.sum(np.isfinite(v))))
                        for p, v in vals.items()}
        print(f"severity {s_norm:.2f}: " + "  ".join(
            f"{p} {'faulty' if p == faulty else 'partner'} F_MTEL {m:.4f} sd {sd:.4f} (n {k})"
            for p, (m, sd, k) in rows[s_norm].items()), flush=True)
    base = rows[SEVERITIES[0]]
    for s_norm in SEVERITIES[1:]:
        d_faulty = rows[s_norm][faulty][0] - base[faulty][0]
        d_partner = rows[s_norm][partner][0] - base[partner][0]
        print(f"severity {s_norm:.2f}: dF faulty {d_faulty:+.4f}, dF partner {d_partner:+.4f}, "
              f"k {d_partner / d_faulty:.3f}; partner shift in its healthy sd "
              f"{d_partner / base[partner][1]:+.2f}")


if __name__ == "__main__":
    main()
