"""Can one active winglet drive hold the tab? Worst-case warps on an active-standby tab.

Healthy aircraft I-OVL01, a 120 s reference cycle warped at 3 sigma (load scale ``sigma_F``
1.9, deflection scale ``sigma_x`` 1.9 or 1.5 with offsets of 3 sigma, or the load alone), WL1
active: the largest |x - x_cmd| of the active drive's LVDT and the largest hinge load at the
rod (both shares). A drive that cannot hold the load is blown back past the stroke. About 10 s
on one core.

Usage: ``python bench/winglet_overload.py``
"""

from __future__ import annotations

import numpy as np

from sim_worker.faults import healthy
from sim_worker.fleet import WINGLET, WingletMode, active_channels, build_aircraft
from sim_worker.flight import run_scenario
from sim_worker.scenario import STROKE_M, Warp, build_scenario

#: (sigma_x, sigma_x0 [m], sigma_F, sigma_F0 [N]) of the winglet
WARPS = ((1.9, 0.3 * STROKE_M, 1.9, 0.3 * WINGLET.nominal_load_n),
         (1.9, -0.3 * STROKE_M, 1.9, -0.3 * WINGLET.nominal_load_n),
         (1.0, 0.0, 1.9, 0.3 * WINGLET.nominal_load_n),
         (1.5, 0.15 * STROKE_M, 1.6, 0.3 * WINGLET.nominal_load_n))


def main() -> None:
    aircraft = build_aircraft("I-OVL01", "Turin", seed=11)
    active = active_channels(WingletMode.ACTIVE_STANDBY, 0)
    for sx, sx0, sf, sf0 in WARPS:
        warp = Warp(sigma_t=1.0, sigma_x=(sx, 1.0), sigma_x0_m=(sx0, 0.0), sigma_f=(sf, 1.0),
                    sigma_f0_n=(sf0, 0.0))
        sc = build_scenario(warp, 15.0, np.random.default_rng(1), duration_s=120.0)
        res = run_scenario(aircraft, healthy(), sc, np.random.default_rng(2), active=active)
        x, x_cmd = res.signals[:, 0, 7], sc.x_cmd[:, 0]
        print(f"sigma_x {sx}, offset {sx0 * 1e3:+.0f} mm, sigma_F {sf}, {sf0:+.0f} N: "
              f"max |x - x_cmd| {np.abs(x - x_cmd).max() * 1e3:.2f} mm, max |x| "
              f"{np.abs(x).max() * 1e3:.1f} mm, hinge load at the rod "
              f"{WINGLET.n_actuators * np.abs(sc.f_ext[:, 0]).max():.0f} N")


if __name__ == "__main__":
    main()
