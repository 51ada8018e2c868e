"""What the LVDTs say about rod-end wear over one REWEAR life, every flight at 12 kHz.

One aircraft, a REWEAR fault on WL1 from onset to failure, every flight simulated (120 s) and
its features computed. With ``--winglet active-active`` it reports the pair feature F_REWEAR;
with ``--winglet active-standby`` the standby's play (``standby_play_feature``) on the flights
WL1 stands by and on those WL2 does, per severity band, and the slope and residual of the
feature on the true added play. About 5 minutes on one core.

Usage: ``python bench/rewear_life.py --winglet active-standby [--span 250] [--seed 21]``
"""

from __future__ import annotations

import argparse

import numpy as np

from server.phm.features import actuator_steps, flight_features, standby_play_feature
from server.vocabulary import SIGNALS, WINGLET_PAIR
from sim_worker.faults import advance_fault, new_fault
from sim_worker.fleet import WingletMode, active_channels, build_aircraft
from sim_worker.flight import reference_summary, simulate_flight

_BANDS = ((0.0, 0.1), (0.1, 0.3), (0.3, 0.5), (0.5, 0.7), (0.7, 0.9), (0.9, 1.01))


def _standby_play(channels: dict[str, np.ndarray], active: str, standby: str) -> float:
    steps = actuator_steps({s: channels[f"{active}.{s}"] for s in SIGNALS})
    return standby_play_feature(channels[f"{active}.x"], channels[f"{standby}.x"],
                                channels[f"{active}.theta"], channels[f"{standby}.theta"],
                                steps.i_q).summary().value


def run_life(mode: WingletMode, span: float, seed: int) -> list[dict[str, float | str]]:
    """Per flight: added play [m], the feature [m] and the drive it reads."""
    aircraft = build_aircraft("I-LIFE01", "Turin", seed=seed)
    ref = reference_summary(aircraft, "WL1", duration_s=120.0, seed=5, winglet_mode=mode)
    fault = new_fault("REWEAR", "WL1", np.random.default_rng(3), reference=ref,
                      span_flights=span, winglet_mode=mode)
    rows: list[dict[str, float | str]] = []
    for n in range(4 * int(span)):
        log, summary = simulate_flight(aircraft, fault, n, np.random.default_rng([9, n]),
                                       winglet_mode=mode)
        ch = {k: np.asarray(v, dtype=np.float64) for k, v in log.channels.items()}
        if mode is WingletMode.ACTIVE_STANDBY:
            active = next(p for p in WINGLET_PAIR if p in active_channels(mode, n))
            standby = next(p for p in WINGLET_PAIR if p != active)
            value, reads = _standby_play(ch, active, standby), standby
        else:
            value, reads = flight_features(ch).summaries["WL1.F_REWEAR"].value, "pair"
        rows.append({"added_m": fault.severity, "sn": fault.severity_norm, "value": value,
                     "reads": reads})
        if fault.failed:
            break
        fault = advance_fault(fault, summary, np.random.default_rng([8, n]))
    return rows


def report(rows: list[dict[str, float | str]]) -> None:
    sn = np.array([r["sn"] for r in rows], dtype=float)
    added = np.array([r["added_m"] for r in rows], dtype=float)
    value = np.array([r["value"] for r in rows], dtype=float)
    reads = np.array([r["reads"] for r in rows])
    print(f"{len(rows)} flights to failure")
    print("| s_n | added play [um] | " + " | ".join(
        f"{d}: mean [um] / sd / valid" for d in dict.fromkeys(reads)) + " |")
    for lo, hi in _BANDS:
        band = (sn >= lo) & (sn < hi)
        cells = []
        for d in dict.fromkeys(reads):
            v = value[band & (reads == d)]
            cells.append(f"{np.nanmean(v) * 1e6:.0f} / {np.nanstd(v) * 1e6:.0f} / "
                         f"{np.mean(np.isfinite(v)):.2f}")
        print(f"| {lo}-{min(hi, 1.0)} | {np.mean(added[band]) * 1e6:.0f} | "
              + " | ".join(cells) + " |")
    worn = np.isfinite(value) & (reads != "WL2")
    slope, icpt = np.polyfit(added[worn], value[worn], 1)
    resid = value[worn] - (slope * added[worn] + icpt)
    print(f"feature on added play (WL1 or pair): slope {slope:.3f}, residual sd "
          f"{np.std(resid) * 1e6:.1f} um")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--winglet", choices=[m.value for m in WingletMode],
                    default=WingletMode.ACTIVE_STANDBY.value)
    ap.add_argument("--span", type=float, default=250.0, help="planned span [flights]")
    ap.add_argument("--seed", type=int, default=21, help="aircraft seed")
    args = ap.parse_args()
    report(run_life(WingletMode(args.winglet), args.span, args.seed))


if __name__ == "__main__":
    main()
