"""Seasonal stress clock: how fast a thermally driven fault ages on each coming flight.

Thermal fault laws age a component faster when it runs hot: insulation life halves per +10 K
(Arrhenius / Montsinger, IEC 60085 practice), grease life per +15 K above 70 degC (the SKF
relubrication rule), a magnet's irreversible loss grows when it runs hot. A fault that grew
slowly through the winter therefore speeds up in spring, and a prognosis that extrapolates the
rate of the past months runs long or short by a factor of several over a 100-200-flight life
(docs/TUNING.md, Season).

The clock counts **stress** instead of flights: a flight at ground temperature T adds
``exp(beta (T - T_ref))`` (1 for a flight at the reference temperature), and the particle
filter's growth law runs in stress units. The temperature of a flight, past or future, is the
base's climatological temperature on its date (:class:`SeasonalClimate`): the weather of one
day averages out over the tens of flights a fault lives, the season does not. ``beta`` per fault
mode is learned on the design runs (``server.phm.training``); wear modes get 0 (a flight clock).

Units: temperatures in degC, beta in 1/K, days of the year from 0 (1 January, 00:00 UTC).
The clock's fixed settings are the defaults of :class:`SeasonConfig`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from datetime import datetime, timedelta

import numpy as np
from numpy.typing import NDArray

__all__ = ["SEASON_DEFAULTS", "SeasonConfig", "SeasonalClimate", "StressClock", "day_of_year",
           "next_flights_per_day"]

_YEAR_DAYS = 365.25
_OMEGA = 2.0 * math.pi / _YEAR_DAYS


@dataclass(frozen=True)
class SeasonConfig:
    """Settings of the climate fit and the stress clock (docs/TUNING.md, Season).

    Attributes
    ----------
    min_flights_per_base:
        Flights with a temperature a base needs before its annual cycle is fitted [flight]:
        eight per coefficient of the one-harmonic model (3 coefficients).
    gap_points:
        Points of the trapezoid mean of the stress rate between two updates [-]: the rate is
        smooth over a gap of a few flights (one annual harmonic).
    flying_rate_weight:
        Weight of the newest observation in the aircraft's exponentially weighted flying
        rate [-]: a memory of about 10 updates.
    """

    min_flights_per_base: int = 24
    gap_points: int = 16
    flying_rate_weight: float = 0.1


#: the settings the chain uses
SEASON_DEFAULTS = SeasonConfig()


def day_of_year(when: datetime) -> float:
    """Fractional day of the year of ``when`` (0 at 1 January 00:00 of its year, UTC)."""
    start = datetime(when.year, 1, 1, tzinfo=when.tzinfo)
    return (when - start).total_seconds() / 86400.0


@dataclass(frozen=True)
class SeasonalClimate:
    """Expected ground temperature of each base over the year [degC]:
    ``T(d) = a0 + a1 cos(w d) + b1 sin(w d)``, w = 2 pi / 365.25 days (one annual harmonic,
    fitted by least squares to the ground temperatures of the design flights)."""

    coefficients: Mapping[str, tuple[float, float, float]]

    @classmethod
    def fit(cls, bases: Sequence[str], days: Sequence[float], temps: Sequence[float]
            ) -> SeasonalClimate:
        """Fit every base that has at least ``SeasonConfig.min_flights_per_base`` (24) flights
        with a finite temperature."""
        b = np.asarray(bases, dtype=object)
        d = np.asarray(days, dtype=float)
        t = np.asarray(temps, dtype=float)
        ok = np.isfinite(d) & np.isfinite(t)
        coef: dict[str, tuple[float, float, float]] = {}
        for base in sorted({str(x) for x in b[ok]}):
            m = ok & (b == base)
            if m.sum() < SEASON_DEFAULTS.min_flights_per_base:
                continue
            X = np.column_stack([np.ones(m.sum()), np.cos(_OMEGA * d[m]), np.sin(_OMEGA * d[m])])
            sol, *_ = np.linalg.lstsq(X, t[m], rcond=None)
            coef[base] = (float(sol[0]), float(sol[1]), float(sol[2]))
        return cls(coef)

    def knows(self, base: str | None) -> bool:
        return base is not None and base in self.coefficients

    def temperature(self, base: str, days: NDArray[np.float64] | float) -> NDArray[np.float64]:
        """Expected ground temperature [degC] at fractional days of the year."""
        a0, a1, b1 = self.coefficients[base]
        d = np.asarray(days, dtype=float)
        return a0 + a1 * np.cos(_OMEGA * d) + b1 * np.sin(_OMEGA * d)

    def to_dict(self) -> dict[str, list[float]]:
        return {k: list(v) for k, v in sorted(self.coefficients.items())}

    @classmethod
    def from_dict(cls, data: Mapping[str, Sequence[float]]) -> SeasonalClimate:
        coef = {}
        for base, v in data.items():
            vals = tuple(float(x) for x in v)
            if len(vals) != 3 or not all(math.isfinite(x) for x in vals):
                raise ValueError(f"climate of {base!r} needs 3 finite coefficients")
            coef[str(base)] = vals
        return cls(coef)


@dataclass(frozen=True)
class StressClock:
    """Stress of the flights of one aircraft for one fault mode.

    ``anchor`` is the take-off time of flight ``anchor_index``; other flights are placed
    ``1 / flights_per_day`` days apart around it (the aircraft's own flying rate).
    ``ref_temp_c`` None: the base's own annual mean temperature (a fault's rate is then stated
    against its base's average season).
    """

    climate: SeasonalClimate
    base: str
    beta_per_k: float
    ref_temp_c: float | None
    anchor: datetime
    anchor_index: int
    flights_per_day: float

    def _rate(self, flights: NDArray[np.float64]) -> NDArray[np.float64]:
        """Stress per flight at (fractional) flight indices."""
        start = day_of_year(self.anchor)
        days = start + (flights - self.anchor_index) / self.flights_per_day
        temp = self.climate.temperature(self.base, np.mod(days, _YEAR_DAYS))
        ref = self.climate.coefficients[self.base][0] if self.ref_temp_c is None \
            else self.ref_temp_c
        return np.exp(self.beta_per_k * (temp - ref))

    def between(self, first: int, last: int) -> float:
        """Stress accumulated from flight ``first`` to flight ``last`` (last - first flights)."""
        if last <= first:
            return 0.0
        x = np.linspace(float(first), float(last), SEASON_DEFAULTS.gap_points)
        return float(np.trapezoid(self._rate(x), x))

    def curve(self, first: int, n_flights: int) -> NDArray[np.float64]:
        """Cumulative stress from flight ``first`` to each of the next ``n_flights`` flights,
        shape (n_flights + 1,), starting at 0."""
        r = self._rate(first + np.arange(n_flights, dtype=float) + 0.5)
        out = np.empty(n_flights + 1)
        out[0] = 0.0
        np.cumsum(r, out=out[1:])
        return out


def next_flights_per_day(previous: float | None, flights: int, since: timedelta,
                         weight: float = SEASON_DEFAULTS.flying_rate_weight) -> float | None:
    """Exponentially weighted flying rate [flight/day] after ``flights`` flights in ``since``."""
    days = since.total_seconds() / 86400.0
    if flights <= 0 or days <= 0:
        return previous
    rate = flights / days
    return rate if previous is None else (1.0 - weight) * previous + weight * rate
