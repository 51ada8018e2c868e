"""Simulated half-wing of the EMA health-management project (the data source).

A real-time-class model (paper section 3.4) of three electromechanical actuators: ``WL1`` and
``WL2`` drive one winglet tab, ``WT`` the wingtip. Fixed step 12 kHz, compiled with numba,
sensor outputs at 800 Hz in flight-log format v1 (:mod:`server.flightlog`). See
``docs/SIMULATOR.md`` for the model, parameters, faults and scenario.

Public API (what the service's sim worker calls)::

    from sim_worker import build_aircraft, new_fault, healthy, simulate_flight, advance_fault

    aircraft = build_aircraft("I-SIM01", "Turin", seed=42)          # production scatter
    fault = new_fault("TTS", "WL1", rng, reference=summary)          # at onset; or healthy()
    log, summary = simulate_flight(aircraft, fault, flight_index, rng)  # FlightLog, FlightSummary
    fault = advance_fault(fault, summary, rng)                       # progression by its law
    data = server.flightlog.write_parquet(log)                       # canonical bytes

* ``build_aircraft(tail: str, base: str, seed: int) -> Aircraft`` with base in
  ``"Turin" | "Vancouver" | "Abu Dhabi"``.
* ``healthy() -> FaultState``; ``new_fault(mode, position, rng, *, reference=None) -> FaultState``
  with mode in ``MODES`` (``TTS DMD SE BDO MTEL MTWEAR REWEAR``); progressive modes need a
  ``reference`` :class:`ActuatorSummary` (e.g. ``reference_summary(aircraft, position, ...)``) to
  calibrate their random rate; ``FaultState(mode, position, severity, threshold, rate)`` can also
  be built directly (e.g. an operator injecting a given severity).
* ``simulate_flight(aircraft, fault, flight_index, rng, *, flight_id=None, started_at=None,
  duration_s=120.0) -> (FlightLog, FlightSummary)``: ``fault`` one :class:`FaultState` or a
  tuple of concurrent ones (each on its position; one of each mode per position). All draws
  come from ``rng`` (seed it per aircraft and flight); the same seed gives the same bytes. A
  batch of one of:
* ``simulate_flights(specs: Sequence[FlightSpec], *, lanes=8) -> list[(FlightLog,
  FlightSummary)]``: several independent flights (``FlightSpec`` holds ``simulate_flight``'s
  arguments, each with its own ``rng``) simulated ``lanes`` at once in the kernel's SIMD lanes,
  in the order of ``specs``, each bit for bit what ``simulate_flight`` gives for it alone.
* ``advance_fault(fault, summary, rng) -> FaultState``: one flight of progression (of each
  concurrent fault by itself, from the same summary).
* ``estimate_summary(aircraft, flight_index, rng, ...) -> FlightSummary``: what a flight would
  do, without the 12 kHz run (for flights that are not rendered; each winglet drive in its
  role).
* ``reference_summary(aircraft, position, *, duration_s, seed) -> ActuatorSummary``: the
  aircraft's average flight (24 estimates over a year), against which a fault's rate is set.
* ``run_campaign(kind, out_dir, *, seed, scale, workers=None)``: see :mod:`sim_worker.campaign`.

Ground truth (severity, threshold, failure flight) lives in :class:`FaultState` and in campaign
manifests, never in the flight log.
"""

from .campaign import run_campaign
from .faults import (
    MODES,
    THRESHOLDS,
    ActuatorSummary,
    FaultState,
    FlightSummary,
    advance_fault,
    healthy,
    new_fault,
)
from .fleet import BASES, POSITIONS, Aircraft, build_aircraft
from .flight import (
    FlightSpec,
    estimate_summary,
    reference_summary,
    simulate_flight,
    simulate_flights,
)

__all__ = [
    "MODES",
    "THRESHOLDS",
    "BASES",
    "POSITIONS",
    "Aircraft",
    "ActuatorSummary",
    "FaultState",
    "FlightSummary",
    "build_aircraft",
    "healthy",
    "new_fault",
    "advance_fault",
    "simulate_flight",
    "simulate_flights",
    "FlightSpec",
    "estimate_summary",
    "reference_summary",
    "run_campaign",
]
