"""progpy's particle filter on a linear-fade model, the obvious alternative to our engine,
scored on the same units by bench/bench_rul_calibration.py (``--progpy``).

State (s, r): severity s drifting at rate r, both random walks; the measurement is s plus
white noise of the robust estimate on the first scored prefix. Time is in spans of that
prefix, so the settings are scale-free as ours: r starts at the prefix's least-squares slope
(sd half of it) and walks 0.5 severity per span per sqrt(span); progpy adds process noise as
dt * N(0, q) per step, so q is that divided by sqrt(dt).
"""

from __future__ import annotations

import math

import numpy as np

from server.phm.prognosis.law_average import robust_noise_std

RATE_WALK, LEVEL_WALK = 0.5, 0.01  # per sqrt(span)


def progpy_forecasts(t: np.ndarray, s: np.ndarray, at: list[int], horizon: float,
                     seed: int = 0) -> list[np.ndarray]:
    """RUL samples (in t's unit) at the sample indices ``at`` (increasing); ``s`` is the
    severity normalised to its threshold 1.0."""
    from progpy import PrognosticsModel  # type: ignore[import-not-found]
    from progpy.state_estimators import ParticleFilter  # type: ignore[import-not-found]
    from progpy.uncertain_data import MultivariateNormalDist  # type: ignore[import-not-found]

    scale = float(t[at[0]] - t[0])
    tau = (t - t[0]) / scale
    first = slice(0, at[0] + 1)
    slope0 = max(float(np.polyfit(tau[first], s[first], 1)[0]), 1e-3)
    sigma = robust_noise_std(s[first])
    dt = float(np.mean(np.diff(tau[first])))

    class LinearFade(PrognosticsModel):  # type: ignore[misc]
        inputs: list[str] = []
        states = ["s", "r"]
        outputs = ["z"]
        events = ["failure"]
        is_vectorized = True
        default_parameters = {  # noqa: RUF012
            "x0": {"s": 0.0, "r": slope0},
            "process_noise": {"s": LEVEL_WALK / math.sqrt(dt), "r": RATE_WALK / math.sqrt(dt)},
            "measurement_noise": {"z": sigma},
        }

        def next_state(self, x, u, dt):  # noqa: ANN001, ANN201
            return self.StateContainer({"s": x["s"] + dt * x["r"], "r": x["r"]})

        def output(self, x):  # noqa: ANN001, ANN201
            return self.OutputContainer({"z": x["s"]})

        def event_state(self, x):  # noqa: ANN001, ANN201
            return {"failure": 1.0 - x["s"]}

        def threshold_met(self, x):  # noqa: ANN001, ANN201
            return {"failure": x["s"] >= 1.0}

    model = LinearFade()
    np.random.seed(seed)  # progpy draws from numpy's global generator
    x0 = MultivariateNormalDist(["s", "r"], [float(np.median(s[:5])), slope0],
                                [[sigma**2 + 1e-8, 0.0], [0.0, (0.5 * slope0) ** 2]])
    filt = ParticleFilter(model, x0, num_particles=200, measurement_noise={"z": sigma})
    out, wanted = [], set(at)
    h = horizon / scale
    for i in range(1, max(at) + 1):
        filt.estimate(float(tau[i]), {}, {"z": float(s[i])})
        if i in wanted:
            out.append(_linear_rul(filt.x, h) * scale)
    return out


def _linear_rul(particles, horizon: float) -> np.ndarray:  # noqa: ANN001
    """Each particle's straight line to s = 1 (progpy's MonteCarlo with the process noise
    off gives the same; it takes 30x longer and its noise scales with its own step)."""
    x = np.array([[p["s"], p["r"]] for p in particles], dtype=float)
    s, r = x[:, 0], x[:, 1]
    rul = np.where(r > 0, (1.0 - s) / np.where(r > 0, r, 1.0), np.inf)
    rul = np.where(s >= 1.0, 0.0, rul)
    return np.where(rul > horizon, np.inf, rul)
