"""The online guard: a unit scores its own short-horizon forecasts and widens its RUL band when
they miss.

After each update the filter forecasts the feature ``guard_horizon`` (K) flights ahead: every
particle rolled K flights on with its own law and the prediction's noise, then the
measurement noise, the central 1 - alpha interval of the weighted draws (alpha =
``guard_miss_rate``). That truth arrives during the life: the first update at or within K/2
flights after the target scores the forecast: a hit, a miss on the fast side (the measured
severity beyond the forecast's, the fault ahead of the filter) or on the slow side. Each side's
widening (log units of 1 + RUL) tracks its misses by the quantile-tracking step of conformal
PID control (Angelopoulos, Candes and Tibshirani, "Conformal PID control for time series
prediction", NeurIPS 2023; the adaptive conformal inference of Gibbs and Candes 2021 in
additive form)::

    w_fast <- max(0, w_fast + gain (miss_fast - alpha / 2))      (and w_slow alike)

so a unit whose forecasts miss more often than alpha, a fault faster or slower than anything
the filter was designed for, widens its own band (each miss adds about gain, each hit takes
gain alpha / 2 back) without any per-unit setting. Fast misses move the bands' lower ends
down (the RUL may be shorter), slow misses their upper ends up, in log(1 + RUL) around the
median (:func:`.calibration.widen`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from .degradation import growth_rate
from .generic import guard_step

if TYPE_CHECKING:  # pragma: no cover - typing only
    from .config import PrognoserConfig
    from .measurement import MeasurementModel

__all__ = ["GuardState", "forecast", "score"]


@dataclass(frozen=True)
class GuardState:
    """The guard of one unit: its widenings of the bands' lower (fast side) and upper ends
    [log(1 + RUL)], the forecasts waiting for their flight ``(target flight, low, high)`` in
    severity, its scored forecasts and the misses on either side."""

    widening_fast: float = 0.0
    widening_slow: float = 0.0
    pending: tuple[tuple[int, float, float], ...] = ()
    scored: int = 0
    missed_fast: int = 0
    missed_slow: int = 0

    @property
    def missed(self) -> int:
        return self.missed_fast + self.missed_slow

    def margins(self) -> dict[float, tuple[float, float]]:
        """The widening of both bands, as :func:`.calibration.widen` takes it."""
        both = (self.widening_fast, self.widening_slow)
        return {0.5: both, 0.9: both}

    def to_dict(self) -> dict[str, Any]:
        return {"widening": [self.widening_fast, self.widening_slow],
                "pending": [list(p) for p in self.pending], "scored": self.scored,
                "missed": [self.missed_fast, self.missed_slow]}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> GuardState:
        pending = tuple((int(t), float(lo), float(hi)) for t, lo, hi in data["pending"])
        fast, slow = (float(w) for w in data["widening"])
        if not all(math.isfinite(w) and w >= 0.0 for w in (fast, slow)):
            raise ValueError("guard widening must be finite and >= 0")
        missed_fast, missed_slow = (int(m) for m in data["missed"])
        return cls(fast, slow, pending, int(data["scored"]), missed_fast, missed_slow)


def score(guard: GuardState, flight: int, severity: float, config: PrognoserConfig
          ) -> GuardState:
    """The guard after the measurement of ``flight``, inverted to ``severity``: forecasts due
    (target <= flight <= target + K/2) scored, older ones dropped unscored (no measurement
    near them)."""
    tolerance = max(1, config.guard_horizon // 2)
    gain, half = config.guard_gain, 0.5 * config.guard_miss_rate
    g = guard
    keep = []
    for target, lo, hi in guard.pending:
        if flight < target:
            keep.append((target, lo, hi))
        elif flight <= target + tolerance:
            fast, slow = severity > hi, severity < lo
            g = replace(g, widening_fast=guard_step(g.widening_fast, fast, gain, half),
                        widening_slow=guard_step(g.widening_slow, slow, gain, half),
                        scored=g.scored + 1, missed_fast=g.missed_fast + int(fast),
                        missed_slow=g.missed_slow + int(slow))
    return replace(g, pending=tuple(keep))


def forecast(guard: GuardState, flight: int, severity: NDArray[np.float64],
             coefficients: NDArray[np.float64], weights: NDArray[np.float64],
             model: MeasurementModel, config: PrognoserConfig, rng: np.random.Generator,
             clock_rate: float = 1.0) -> GuardState:
    """The guard with the forecast of the measured severity ``guard_horizon`` flights after
    ``flight`` added: each particle rolled on with its law ``coefficients`` ((p,) or (N, p))
    and the prediction's noise, one measurement draw each inverted to severity (as the
    measurement will be), the weighted central interval.
    ``clock_rate`` is the law's clock per flight over the coming flights (the last update's:
    a thermal mode ages faster in summer, :mod:`server.phm.season`)."""
    h = severity.copy()
    q = config.prediction_noise * math.sqrt(clock_rate)
    for _ in range(config.guard_horizon):
        h += clock_rate * growth_rate(h, coefficients, config.min_rate)
        h += q * rng.standard_normal(h.size)
        np.maximum(h, 0.0, out=h)
    z = model.invert(model.predict(h) + model.noise_at(h) * rng.standard_normal(h.size))
    order = np.argsort(z)
    cdf = np.cumsum(weights[order])
    half = 0.5 * config.guard_miss_rate
    lo = float(z[order][min(int(np.searchsorted(cdf, half)), z.size - 1)])
    hi = float(z[order][min(int(np.searchsorted(cdf, 1.0 - half)), z.size - 1)])
    return replace(guard, pending=(*guard.pending, (flight + config.guard_horizon, lo, hi)))
