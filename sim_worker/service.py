"""The sim worker as a service: fly the simulated fleet, honour test-station injections, upload
every flight over REST and report ground truth (``sim-worker run``).

Per aircraft and flight number ``n`` (flight id ``<tail>-F<n:05d>``), three requests:

1. ``GET /test-station/plan?aircraft=&flight=n``: the aircraft (its installed units) and what
   the test station has on flight ``n``: the live fault injections (each taken up at its
   onset; a cancelled injection or a replaced actuator clears its fault), the sensor
   injections and the conditions;
2. simulate flight ``n`` with every live injection's fault on board (concurrent faults: on
   other actuators, or other modes on one; its sensor injections in the sensor models the
   loops close on, its conditions in its scenario and thermal model), then advance each fault
   by its own law from what the flight did, each steered to fail at its planned flight
   (:mod:`.steering`: the operator's time to failure, or one drawn by the campaigns' law,
   counted from the flight the fault started on) on its own random stream;
   ``PUT /test-station/flights/<flight id>``: every item's truth on the flight at once (each
   fault's severity as the flight began, its planned failure flight, and at the threshold the
   flight it fails from: the service marks that injection and the unit failed and back-fills
   the true RUL of every flight it reported, only known in hindsight; each sensor injection's
   and condition's applied value, :data:`APPLIED`) -- idempotent, skipped when nothing is on
   the flight;
3. upload it -- idempotent: the same seed gives the same bytes, and the service answers 200
   for bytes it already has.

**A failed drive grounds its aircraft.** A flight-control actuator at failure is a no-go item:
from the flight the drive fails from the aircraft does not fly (``fly`` returns ``"grounded"``,
nothing is uploaded or reported) until the failed unit is replaced (its serial changes on the
service, which then holds a healthy unit and has ended every injection on it: a second fault
on that unit is cancelled, its RUL never known). A failure ends that injection only: a fault
on another actuator flies on once the aircraft flies again. The fault is never healed while
the unit is installed: not when its injection is no longer live (a failed injection is not),
not on a restart (the service's actuator says ``failed_at_flight``).

Every request is retried with exponential backoff until it succeeds, so an API outage delays
flights but never loses or duplicates one. On restart the worker resumes after the last flight
it uploaded, or at a flight it reported but did not upload (re-running that is harmless), with
the severity from its ground truth. (An uploaded flight is not flown again: after a replacement
its serials, hence its bytes, would differ from the stored ones.)
"""

from __future__ import annotations

import logging
import re
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import httpx
import numpy as np

from server.flightlog import write_parquet

from .conditions import from_api as conditions_from_api
from .faults import FaultState, FlightSummary, advance_fault
from .fleet import FLEET_BASES, Aircraft, build_aircraft
from .flight import flight_start, reference_summary, simulate_flight
from .sensors import SensorInjection, degrade
from .steering import SteeredFault, plan_fault, steer_and_advance

__all__ = ["Api", "ApiError", "SimFleetRunner", "fleet_plan"]

log = logging.getLogger("sim_worker.service")

_RETRYABLE = {429, 500, 502, 503, 504}


def _condition_applied(doc: dict[str, Any], n: int, summary: FlightSummary) -> float:
    """A condition's truth: its value, or for a base the ground temperature flown."""
    return summary.ground_temp_c if doc["kind"] == "base" else float(doc["value"])


#: the simulator's side of the test-station kinds it flies as given (the fault, whose state
#: the runner steers, is its own): per kind of the flight plan, what an item did to flight
#: ``n`` (its truth). Their effect on the flight is in ``fly``'s call to the simulation
APPLIED: dict[str, Callable[[dict[str, Any], int, FlightSummary], float]] = {
    "sensor_injections": lambda doc, n, summary: SensorInjection.from_api(doc, n).applied(n),
    "conditions": _condition_applied,
}


class ApiError(RuntimeError):
    """A request the service refused for good (4xx other than 409/422 handled by callers)."""

    def __init__(self, status: int, body: Any):
        super().__init__(f"HTTP {status}: {body}")
        self.status = status
        self.body = body


class Api:
    """HTTP client of the HMSM with retries and exponential backoff (no request is dropped)."""

    def __init__(self, base_url: str, key: str, *, operator_key: str | None = None,
                 max_backoff_s: float = 30.0, sleep: Callable[[float], None] = time.sleep,
                 stop: Callable[[], bool] = lambda: False):
        self.base = base_url.rstrip("/") + "/api/v1"
        self.client = httpx.Client(timeout=60.0)
        self.key = key
        self.operator_key = operator_key or key
        self.max_backoff_s = max_backoff_s
        self.sleep = sleep
        self.stop = stop

    def request(self, method: str, path: str, *, operator: bool = False, ok: tuple[int, ...] = (
            200, 201, 202), **kwargs: Any) -> httpx.Response:
        key = self.operator_key if operator else self.key
        headers = {"Authorization": f"Bearer {key}", **kwargs.pop("headers", {})}
        delay = 0.5
        while True:
            try:
                response = self.client.request(method, self.base + path, headers=headers,
                                               **kwargs)
                if response.status_code in ok:
                    return response
                if response.status_code not in _RETRYABLE:
                    raise ApiError(response.status_code, _body(response))
                log.warning("%s %s: HTTP %s, retrying in %.1f s", method, path,
                            response.status_code, delay)
            except httpx.TransportError as exc:
                log.warning("%s %s: %s, retrying in %.1f s", method, path, exc, delay)
            if self.stop():
                raise InterruptedError("stopped while retrying")
            self.sleep(delay)
            delay = min(self.max_backoff_s, delay * 2)

    def close(self) -> None:
        self.client.close()


def _body(response: httpx.Response) -> Any:
    try:
        return response.json()
    except ValueError:
        return response.text[:500]


def fleet_plan(n_aircraft: int, seed: int, prefix: str = "SIM") -> list[Aircraft]:
    """The simulated fleet: tails SIM01.., bases 4 Turin, 3 Vancouver, 3 Abu Dhabi per ten."""
    return [build_aircraft(f"{prefix}{i + 1:02d}", FLEET_BASES[i % len(FLEET_BASES)],
                           int(np.random.SeedSequence([seed, 7, i]).generate_state(1)[0]))
            for i in range(n_aircraft)]


@dataclass
class FaultRun:
    """One fault injection as the runner flies it: its fault now, its plan, and the flight its
    drive fails from once it reached the threshold."""

    injection_id: int
    fault: FaultState
    #: a progressive injection's plan (None for abrupt faults)
    plan: SteeredFault | None = None
    failed_at: int | None = None


@dataclass
class AircraftRun:
    aircraft: Aircraft
    index: int
    next_flight: int
    #: the injections it flies, by id, in the order it took them up: concurrent faults
    injections: dict[int, FaultRun] = field(default_factory=dict)

    @property
    def faults(self) -> tuple[FaultState, ...]:
        """The faults on board, in the order their injections were taken up."""
        return tuple(r.fault for r in self.injections.values())

    @property
    def failed_at(self) -> int | None:
        """The earliest flight a drive of the aircraft fails from (None: none failed)."""
        return min((r.failed_at for r in self.injections.values() if r.failed_at is not None),
                   default=None)


class SimFleetRunner:
    """Flies ``n_aircraft`` simulated aircraft at ``rate_per_min`` flights a minute in total."""

    def __init__(self, api: Api, *, n_aircraft: int, rate_per_min: float, seed: int = 0,
                 duration_s: float = 120.0, prefix: str = "SIM",
                 sleep: Callable[[float], object] = time.sleep):
        if n_aircraft < 1 or rate_per_min <= 0 or duration_s < 15:
            raise ValueError("need n_aircraft >= 1, rate > 0 and duration >= 15 s")
        self.api = api
        self.seed = seed
        self.duration_s = duration_s
        self.interval_s = 60.0 / rate_per_min
        self.sleep = sleep
        self.runs = [AircraftRun(a, i, 1) for i, a in
                     enumerate(fleet_plan(n_aircraft, seed, prefix))]

    # -- set-up and recovery ------------------------------------------------------------------

    def register_fleet(self) -> None:
        """Register missing aircraft (needs an admin key) and adopt installed serials."""
        for run in self.runs:
            tail = run.aircraft.tail
            response = self.api.request("GET", f"/aircraft/{tail}", ok=(200, 404))
            if response.status_code == 404:
                response = self.api.request("POST", "/aircraft", ok=(201, 409), json={
                    "tail": tail, "base": run.aircraft.base,
                    "actuators": dict(run.aircraft.serials)})
                if response.status_code == 409:
                    response = self.api.request("GET", f"/aircraft/{tail}")
            self._adopt_serials(run, response.json())
            self._resume(run)

    def _adopt_serials(self, run: AircraftRun, aircraft_doc: dict[str, Any]) -> None:
        installed = {p: a["serial"] for p, a in aircraft_doc["actuators"].items()}
        if installed != run.aircraft.serials:
            changed = {p for p, s in installed.items() if run.aircraft.serials.get(p) != s}
            for inj_id, held in list(run.injections.items()):
                if held.fault.position in changed:
                    log.info("%s: actuator %s replaced; its %s is gone", run.aircraft.tail,
                             held.fault.position, held.fault.mode)
                    del run.injections[inj_id]
            run.aircraft = replace(run.aircraft, serials=installed)

    def _resume(self, run: AircraftRun) -> None:
        tail = run.aircraft.tail
        pattern = re.compile(rf"^{re.escape(tail)}-F(\d+)$")
        last, offset = 0, 0  # the last flight uploaded
        while True:
            page = self.api.request("GET", f"/flights?aircraft={tail}&limit=500&offset={offset}"
                                    ).json()
            for item in page["items"]:
                m = pattern.match(item.get("flight") or "")
                if m:
                    last = max(last, int(m.group(1)))
            offset += len(page["items"])
            if offset >= page["total"] or not page["items"]:
                break
        # a flight's truth is reported before its upload: the next flight may be one reported
        # and not uploaded, flown again from the same state (harmless)
        run.next_flight = last + 1
        for injection in self._plan(run)["injections"]:
            if injection["status"] != "pending":
                self._resume_injection(run, injection)

    def _resume_injection(self, run: AircraftRun, injection: dict[str, Any]) -> None:
        """Take up an injection flown before a restart, at the severity of its last truth."""
        truth = self.api.request(
            "GET", f"/test-station/injections/{injection['id']}/ground-truth").json()
        if not truth:
            return
        # the driver history is not stored: the plan restarts from its prior
        held = self._start(run, injection, int(truth[0]["flight_number"]))
        held.fault = replace(held.fault, severity=float(truth[-1]["severity"]))
        if held.plan is not None:
            held.plan = replace(held.plan, state=held.fault)
        if injection.get("failure_flight") is not None:
            held.failed_at = int(injection["failure_flight"])

    def _plan(self, run: AircraftRun) -> dict[str, Any]:
        """What the service has on the aircraft for its next flight: the aircraft (installed
        units) and, per test-station kind, the items to fly."""
        return self.api.request("GET", f"/test-station/plan?aircraft={run.aircraft.tail}"
                                f"&flight={run.next_flight}").json()

    # -- injections ---------------------------------------------------------------------------

    def _start(self, run: AircraftRun, injection: dict[str, Any], start_flight: int
               ) -> FaultRun:
        """Take up the injection's fault, started at ``start_flight``; the same on every
        restart (seeded by its id). A progressive fault is planned to fail ``span`` flights
        after its start: the operator's time to failure, or drawn as campaigns draw it."""
        rng = np.random.default_rng([self.seed, 11, run.index, int(injection["id"])])
        # the aircraft's average flight at this runner's recording length, as campaigns do:
        # one drawn flight could be a short, calm one and make the fault fail far too soon
        reference = reference_summary(run.aircraft, injection["position"],
                                      duration_s=self.duration_s,
                                      seed=(self.seed, 12, run.index))
        fault, plan = plan_fault(
            injection["fault_mode"], injection["position"], rng, reference=reference,
            start_flight=start_flight, span_flights=injection["time_to_failure_flights"],
            severity_norm=injection.get("severity"), base=run.aircraft.base)
        held = run.injections[int(injection["id"])] = FaultRun(int(injection["id"]), fault, plan)
        return held

    def _sync_injections(self, run: AircraftRun, n: int, planned: list[dict[str, Any]]
                         ) -> None:
        """Take up the faults the plan of flight ``n`` holds, and drop those it no longer
        holds (a cancelled injection: its drive flies on without that fault); a failed one is
        kept until its unit is replaced."""
        live = {int(doc["id"]): doc for doc in planned}
        for inj_id, held in list(run.injections.items()):
            if inj_id not in live and held.failed_at is None:
                log.info("%s: injection %s ended; %s on %s is gone", run.aircraft.tail, inj_id,
                         held.fault.mode, held.fault.position)
                del run.injections[inj_id]
        for inj_id, doc in live.items():
            if inj_id not in run.injections:
                held = self._start(run, doc, n)
                log.info("%s: %s on %s from flight %d", run.aircraft.tail, held.fault.mode,
                         held.fault.position, n)

    # -- one flight ---------------------------------------------------------------------------

    @staticmethod
    def failed_positions(aircraft_doc: dict[str, Any]) -> dict[str, int]:
        """Position -> failure flight of the installed units the service holds as failed."""
        return {p: int(a["failed_at_flight"]) for p, a in aircraft_doc["actuators"].items()
                if a.get("failed_at_flight") is not None}

    def grounded(self, run: AircraftRun, aircraft_doc: dict[str, Any], n: int) -> bool:
        """The documented rule: an aircraft with a failed drive installed does not fly (a
        drive failed from flight ``f`` still flew flight ``f - 1``)."""
        failures = [*self.failed_positions(aircraft_doc).values(),
                    *(r.failed_at for r in run.injections.values() if r.failed_at is not None)]
        return any(f <= n for f in failures)

    def fly(self, run: AircraftRun) -> str:
        """Fly, report and upload the aircraft's next flight (three requests: its plan, its
        truth, the upload); return the upload outcome, or ``"grounded"`` (nothing flown)
        while a failed drive is installed."""
        n = run.next_flight
        tail = run.aircraft.tail
        plan = self._plan(run)
        self._adopt_serials(run, plan["aircraft"])
        if self.grounded(run, plan["aircraft"], n):
            return "grounded"
        self._sync_injections(run, n, plan["injections"])
        flight_id = f"{tail}-F{n:05d}"
        sensors = [SensorInjection.from_api(doc, n) for doc in plan["sensor_injections"]]
        rng = np.random.default_rng([self.seed, 13, run.index, n])
        flight_log, summary = simulate_flight(
            degrade(run.aircraft, sensors, n), run.faults, n, rng, flight_id=flight_id,
            started_at=flight_start(n), duration_s=self.duration_s,
            conditions=conditions_from_api(plan["conditions"]))
        # each fault's truth on flight n is its state when the flight began
        flown = {inj_id: held.fault for inj_id, held in run.injections.items()}
        for held in run.injections.values():
            self._advance(run, held, summary, n)
        truth = {"injections": self._fault_truths(run, flown, n), **{
            key: [{"id": int(doc["id"]), "applied": applied(doc, n, summary)}
                  for doc in plan[key]] for key, applied in APPLIED.items()}}
        if any(truth.values()):  # before the upload: a restart flies it again, harmlessly
            self.api.request("PUT", f"/test-station/flights/{flight_id}", operator=True,
                             json={"aircraft": tail, "flight_number": n, **truth})
        response = self.api.request(
            "POST", "/flights", ok=(200, 202, 409, 422), content=write_parquet(flight_log),
            headers={"Content-Type": "application/vnd.apache.parquet"})
        outcome = {200: "duplicate", 202: "accepted", 409: "conflict", 422: "rejected"}[
            response.status_code]
        if outcome in ("conflict", "rejected"):
            log.error("%s: upload %s: %s", flight_id, outcome, _body(response))
        run.next_flight = n + 1
        return outcome

    def _advance(self, run: AircraftRun, held: FaultRun, summary: FlightSummary, n: int
                 ) -> None:
        """One injection's fault after flight ``n``, by its law from what the flight did, on
        its own random stream (the other faults' draws do not move it); at the failure
        threshold its drive is failed from the next flight."""
        if held.failed_at is not None:
            return
        rng = np.random.default_rng([self.seed, 14, run.index, n, held.injection_id])
        if held.plan is not None:
            held.plan = steer_and_advance(held.plan, summary, n, rng)
            held.fault = held.plan.state
        else:
            held.fault = advance_fault(held.fault, summary, rng)
        if held.fault.failed:
            held.failed_at = n + 1
            log.info("%s: %s on %s reached failure at flight %d", run.aircraft.tail,
                     held.fault.mode, held.fault.position, n + 1)

    @staticmethod
    def _fault_truths(run: AircraftRun, flown: dict[int, FaultState], n: int
                      ) -> list[dict[str, Any]]:
        """Each fault's truth on flight ``n``: its state as the flight began (``flown``, by
        injection id), its plan, and the flight it fails from once known (the service then
        gives every flight it reported its true RUL)."""
        truths = []
        for inj_id, state in flown.items():
            held = run.injections[inj_id]
            truths.append({
                "id": inj_id, "severity": float(state.severity),
                "severity_norm": float(state.severity_norm),
                "true_rul_flights": None if held.failed_at is None
                else max(held.failed_at - n, 0),
                "planned_failure_flight": None if held.plan is None
                else held.plan.target_flight,
                "failure_flight": held.failed_at})
        return truths

    # -- the loop -----------------------------------------------------------------------------

    def run(self, *, max_flights: int | None = None, stop: Callable[[], bool] = lambda: False
            ) -> int:
        """Fly round-robin at the configured rate; return the number of flights flown."""
        self.register_fleet()
        flown = turn = grounded_in_a_row = 0
        next_at = time.monotonic()
        while not stop() and (max_flights is None or flown < max_flights):
            run = self.runs[turn % len(self.runs)]
            turn += 1
            try:
                outcome = self.fly(run)
            except InterruptedError:
                break
            if outcome == "grounded":
                grounded_in_a_row += 1
                if grounded_in_a_row >= len(self.runs):  # the whole fleet is grounded
                    if max_flights is not None:
                        break
                    grounded_in_a_row = 0
                    self.sleep(self.interval_s)
                continue
            grounded_in_a_row = 0
            flown += 1
            log.info("%s-F%05d %s (%s)", run.aircraft.tail, run.next_flight - 1, outcome,
                     ", ".join(f"{f.mode} on {f.position}" for f in run.faults) or "healthy")
            next_at += self.interval_s
            wait = next_at - time.monotonic()
            if wait > 0:
                self.sleep(wait)
            elif wait < -10 * self.interval_s:
                next_at = time.monotonic()  # far behind (slow machine): do not burst
        return flown
