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

Mean driver: ``D = (w0 d_ref + sum_k d_k) / (w0 + n)``, with ``d_k`` the driver of flight ``k``
measured at 12 kHz and the reference driver ``d_ref`` as a prior worth ``w0 = 3`` flights (one
flight alone is a noisy estimate of a mean).
"""

from __future__ import annotations

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

__all__ = ["SteeredFault", "plan_fault", "steer_and_advance"]

_PRIOR_FLIGHTS = 3.0
_OVERDUE_FLIGHTS = 0.1


@dataclass(frozen=True)
class SteeredFault:
    """A progressive fault planned to reach its threshold at ``target_flight`` (the first
    flight the drive is failed at)."""

    state: FaultState
    target_flight: int
    reference_driver: float
    driver_sum: float = 0.0
    flights: int = 0

    @property
    def mean_driver(self) -> float:
        return ((_PRIOR_FLIGHTS * self.reference_driver + self.driver_sum)
                / (_PRIOR_FLIGHTS + self.flights))


def plan_fault(mode: str, position: str, rng: np.random.Generator, *,
               reference: ActuatorSummary, start_flight: int, span_flights: float | None = None,
               severity_norm: float | None = None) -> tuple[FaultState, SteeredFault | None]:
    """A test-station fault at its start, and for a progressive mode its plan: failure
    ``span_flights`` after ``start_flight`` (drawn from the campaigns' range when None, with the
    draw :func:`~sim_worker.faults.new_fault` would make)."""
    if mode in PROGRESSIVE and span_flights is None:
        span_flights = float(rng.uniform(*SPAN_FLIGHTS))
    fault = new_fault(mode, position, rng, reference=reference, span_flights=span_flights,
                      severity_norm=severity_norm)
    if mode not in PROGRESSIVE or span_flights is None:
        return fault, None
    return fault, SteeredFault(fault, target_flight=start_flight + round(span_flights),
                               reference_driver=reference_driver(mode, reference))


def steer_and_advance(fault: SteeredFault, summary: FlightSummary, flight: int,
                      rng: np.random.Generator) -> SteeredFault:
    """Fault after ``flight``: re-plan the rate from the drivers measured so far (this flight
    included), then grow the fault by its law from what the flight did."""
    st = fault.state
    if st.position is None or st.failed:
        return fault
    flown_driver = driver(st.mode, summary.actuators[st.position], summary.block_hours)
    measured = replace(fault, driver_sum=fault.driver_sum + flown_driver,
                       flights=fault.flights + 1)
    # flight n covers [n, n + 1): failing at the target flight T means crossing the threshold
    # during flight T - 1, so the plan aims at its middle; an overdue fault is planned to
    # finish within a tenth of a flight (a calm flight can still leave it short)
    flights_left = max(fault.target_flight - 0.5 - flight, _OVERDUE_FLIGHTS)
    rate = life_to_go(st) / (flights_left * max(measured.mean_driver, 1e-9))
    return replace(measured, state=advance_fault(replace(st, rate=rate), summary, rng))

