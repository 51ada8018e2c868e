"""The online guard: a unit scores its own short-horizon forecasts and widens its RUL band when
they miss.

After each update the filter forecasts the feature ``guard_horizon`` (K) flights ahead: every
particle rolled K flights on with its own law and the prediction's noise, then the
measurement noise, the central 1 - alpha interval of the weighted draws (alpha =
``guard_miss_rate``). That truth arrives during the life: the first update at or within K/2
flights after the target scores the forecast, hit or miss. The widening w (log units of
1 + RUL) tracks the misses by the quantile-tracking step of conformal PID control (Angelopoulos,
Candes and Tibshirani, "Conformal PID control for time series prediction", NeurIPS 2023; the
adaptive conformal inference of Gibbs and Candes 2021 in additive form)::

    w <- max(0, w + gain (miss - alpha))

so a unit whose forecasts miss more often than alpha, a fault faster or slower than anything
the filter was designed for, widens its own band (each miss adds gain (1 - alpha), each hit
takes gain alpha back) without any per-unit setting. The band is widened in log(1 + RUL)
around the median (:func:`.calibration.widen`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from .degradation import growth_rate

if TYPE_CHECKING:  # pragma: no cover - typing only
    from .config import PrognoserConfig
    from .measurement import MeasurementModel

__all__ = ["GuardState", "forecast", "score"]


@dataclass(frozen=True)
class GuardState:
    """The guard of one unit: its widening [log(1 + RUL)], the forecasts waiting for their
    flight ``(target flight, low, high)`` [feature unit], and its scored and missed counts."""

    widening: float = 0.0
    pending: tuple[tuple[int, float, float], ...] = ()
    scored: int = 0
    missed: int = 0

    def to_dict(self) -> dict[str, Any]:
        return {"widening": self.widening, "pending": [list(p) for p in self.pending],
                "scored": self.scored, "missed": self.missed}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> GuardState:
        pending = tuple((int(t), float(lo), float(hi)) for t, lo, hi in data["pending"])
        widening = float(data["widening"])
        if not (math.isfinite(widening) and widening >= 0.0):
            raise ValueError("guard widening must be finite and >= 0")
        return cls(widening, pending, int(data["scored"]), int(data["missed"]))


def score(guard: GuardState, flight: int, feature: float, config: PrognoserConfig
          ) -> GuardState:
    """The guard after the measurement ``feature`` of ``flight``: forecasts due (target <=
    flight <= target + K/2) scored, older ones dropped unscored (no measurement near them)."""
    tolerance = max(1, config.guard_horizon // 2)
    widening, scored, missed = guard.widening, guard.scored, guard.missed
    keep = []
    for target, lo, hi in guard.pending:
        if flight < target:
            keep.append((target, lo, hi))
        elif flight <= target + tolerance:
            miss = not (lo <= feature <= hi)
            widening = max(0.0, widening + config.guard_gain
                           * (float(miss) - config.guard_miss_rate))
            scored += 1
            missed += int(miss)
    return GuardState(widening, tuple(keep), scored, missed)


def forecast(guard: GuardState, flight: int, severity: NDArray[np.float64],
             coefficients: NDArray[np.float64], weights: NDArray[np.float64],
             model: MeasurementModel, config: PrognoserConfig, rng: np.random.Generator,
             clock_rate: float = 1.0) -> GuardState:
    """The guard with the forecast of the feature ``guard_horizon`` flights after ``flight``
    added: each particle rolled on with its law ``coefficients`` ((p,) or (N, p)) and the
    prediction's noise, one measurement draw each, the weighted central interval.
    ``clock_rate`` is the law's clock per flight over the coming flights (the last update's:
    a thermal mode ages faster in summer, :mod:`server.phm.season`)."""
    h = severity.copy()
    q = config.prediction_noise * math.sqrt(clock_rate)
    for _ in range(config.guard_horizon):
        h += clock_rate * growth_rate(h, coefficients, config.min_rate)
        h += q * rng.standard_normal(h.size)
        np.maximum(h, 0.0, out=h)
    z = model.predict(h) + model.noise_at(h) * rng.standard_normal(h.size)
    order = np.argsort(z)
    cdf = np.cumsum(weights[order])
    half = 0.5 * config.guard_miss_rate
    lo = float(z[order][min(np.searchsorted(cdf, half), z.size - 1)])
    hi = float(z[order][min(np.searchsorted(cdf, 1.0 - half), z.size - 1)])
    return replace(guard, pending=(*guard.pending, (flight + config.guard_horizon, lo, hi)))
