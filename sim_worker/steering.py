"""A test-station fault steered to fail at the flight the operator asked for.

A campaign draws a progression rate once per pattern from the *expected* conditions of the
aircraft's base (:func:`~sim_worker.flight.reference_summary`, a year's average), so its spans
spread with season and usage as real lives do. A test-station operator instead asks for a
time to failure: "MTEL on WT, failure in 60 flights". The reference year does not hold for a
given 60 flights (a cold month ages grease far slower than the annual mean; the 12 kHz flights
run cooler or warmer than the estimate), so a rate fixed at onset misses the request by tens
of percent.

The station therefore steers the rate the way an accelerated-ageing rig steers its stress:
after each flight it re-plans the rate constant so that the *expected* remaining progression,
at the mean driver measured on the flights flown so far, reaches the failure threshold at the
planned flight. The law of the mode is untouched -- each flight still grows the fault by
``rate * driver(flight) * (s + c)`` with its random factor, so a hot flight still ages a
drive more than a cold one -- only the constant is re-estimated. The planned failure flight
is known to the station from onset: it is the live "true RUL" the test station shows.

The flights to come are expected to follow the base's season, as a campaign's faults do: a
thermal mode's expected driver on flight ``j`` is the reference flight's at the winding
temperature shifted by the base's climatological offset for that date, ``e_j``
(:func:`~sim_worker.fleet.seasonal_offset_c`; wear modes do not depend on temperature, so
``e_j = d_ref``). The flights flown so far scale that expectation by their measured ratio
``K = (w0 + sum_k d_k / e_k) / (w0 + n)``, ``d_k`` the driver of flight ``k`` measured at
12 kHz, with a prior worth ``w0 = 3`` flights of "as expected" (one flight alone is a noisy
estimate of a mean). The rate constant is then the one whose expected progression,
``rate K sum_j e_j`` over the flights left, reaches the threshold. A fault injected in August
at Turin therefore slows into the autumn as a real one would (a hotter rate early, a colder
season later) instead of holding the summer's pace by a rate raised flight after flight: the
law the prognosis learned from the campaigns' faults, on its stress clock, still holds for a
steered one (with the flights' mean in place of the season's, a 148-flight TTS from August
was predicted 45 flights late at mid-life).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from .faults import (
    PROGRESSIVE,
    SPAN_FLIGHTS,
    ActuatorSummary,
    FaultState,
    FlightSummary,
    advance_fault,
    driver,
    life_to_go,
    new_fault,
    reference_driver,
)
from .fleet import seasonal_offset_c
from .flight import days_of_year

__all__ = ["SteeredFault", "plan_fault", "steer_and_advance"]

_PRIOR_FLIGHTS = 3.0
_OVERDUE_FLIGHTS = 0.1


@dataclass(frozen=True)
class SteeredFault:
    """A progressive fault planned to reach its threshold at ``target_flight`` (the first
    flight the drive is failed at)."""

    state: FaultState
    target_flight: int
    reference: ActuatorSummary
    #: the aircraft's base, whose season the flights to come are expected to follow; None:
    #: every flight expected at the reference driver
    base: str | None = None
    #: sum over the flights flown of their driver over the driver expected for their date
    ratio_sum: float = 0.0
    flights: int = 0

    @property
    def mean_ratio(self) -> float:
        """``K``: how much harder than expected for their season the flights flown so far
        drove the fault, with a prior of ``_PRIOR_FLIGHTS`` flights as expected."""
        return (_PRIOR_FLIGHTS + self.ratio_sum) / (_PRIOR_FLIGHTS + self.flights)

    def expected_drivers(self, flights: np.ndarray) -> np.ndarray:
        """The driver each of ``flights`` is expected to have at the base's climate for its
        date (the reference flight's winding temperature shifted by the season's offset)."""
        mode = self.state.mode
        if self.base is None:
            return np.full(len(flights), reference_driver(mode, self.reference))
        # a wear mode's driver ignores the winding temperature: its expectation stays flat
        offsets = seasonal_offset_c(self.base, days_of_year(flights))
        return np.array([reference_driver(mode, replace(
            self.reference, winding_mean_c=self.reference.winding_mean_c + float(dt)))
            for dt in offsets])


def plan_fault(mode: str, position: str, rng: np.random.Generator, *,
               reference: ActuatorSummary, start_flight: int, span_flights: float | None = None,
               severity_norm: float | None = None, base: str | None = None
               ) -> tuple[FaultState, SteeredFault | None]:
    """A test-station fault at its start, and for a progressive mode its plan: failure
    ``span_flights`` after ``start_flight`` (drawn from the campaigns' range when None, with the
    draw :func:`~sim_worker.faults.new_fault` would make), the flights to come expected to
    follow the season of ``base``."""
    if mode in PROGRESSIVE and span_flights is None:
        span_flights = float(rng.uniform(*SPAN_FLIGHTS))
    fault = new_fault(mode, position, rng, reference=reference, span_flights=span_flights,
                      severity_norm=severity_norm)
    if mode not in PROGRESSIVE or span_flights is None:
        return fault, None
    return fault, SteeredFault(fault, target_flight=start_flight + round(span_flights),
                               reference=reference, base=base)


def steer_and_advance(fault: SteeredFault, summary: FlightSummary, flight: int,
                      rng: np.random.Generator) -> SteeredFault:
    """Fault after ``flight``: re-plan the rate from the drivers measured so far (this flight
    included), then grow the fault by its law from what the flight did."""
    st = fault.state
    if st.position is None or st.failed:
        return fault
    flown_driver = driver(st.mode, summary.actuators[st.position], summary.block_hours)
    # flight n covers [n, n + 1): failing at the target flight T means crossing the threshold
    # during flight T - 1, so the plan aims at its middle; an overdue fault is planned to
    # finish within a tenth of a flight (a calm flight can still leave it short)
    flights_left = max(fault.target_flight - 0.5 - flight, _OVERDUE_FLIGHTS)
    expected = fault.expected_drivers(np.arange(flight, flight + math.ceil(flights_left)))
    measured = replace(fault, ratio_sum=fault.ratio_sum + flown_driver / expected[0],
                       flights=fault.flights + 1)
    rate = life_to_go(st) / (flights_left * max(measured.mean_ratio * expected.mean(), 1e-9))
    return replace(measured, state=advance_fault(replace(st, rate=rate), summary, rng))

