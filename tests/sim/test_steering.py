"""The test station's steered fault (``sim_worker/steering.py``): it fails at the planned flight
whatever the flights turn out to be, while each flight still grows it by the mode's law."""

from __future__ import annotations

import numpy as np
import pytest

from sim_worker.faults import ActuatorSummary, FlightSummary, advance_fault, driver
from sim_worker.fleet import monthly_climate, seasonal_offset_c
from sim_worker.flight import days_of_year
from sim_worker.steering import plan_fault, steer_and_advance

_REF = ActuatorSummary(winding_mean_c=55.0, winding_max_c=70.0, current_rms_a=3.0,
                       load_rms_n=900.0, work_screw_n_m=300.0, work_rod_end_n_m=300.0,
                       travel_m=0.4)


def _flight(position: str, hotter_k: float, work_factor: float, block_hours: float
            ) -> FlightSummary:
    """A flight at the reference conditions, hotter by ``hotter_k`` and with its sliding work
    times ``work_factor``."""
    s = ActuatorSummary(**{**_REF.__dict__,
                           "winding_mean_c": _REF.winding_mean_c + hotter_k,
                           "work_screw_n_m": _REF.work_screw_n_m * work_factor,
                           "work_rod_end_n_m": _REF.work_rod_end_n_m * work_factor})
    return FlightSummary(actuators={position: s}, block_hours=block_hours, ground_temp_c=15.0,
                         duration_s=60.0, measured=True)


def _fly(mode: str, position: str, span: int, *, steered: bool, colder_k: float,
         calmer: float, seed: int) -> int:
    """Flights from the start to failure, on flights colder and calmer than the reference."""
    rng = np.random.default_rng(seed)
    fault, plan = plan_fault(mode, position, rng, reference=_REF, start_flight=100,
                             span_flights=float(span))
    n = 100
    while not fault.failed and n < 100 + 5 * span:
        summary = _flight(position, -colder_k + rng.normal(0.0, 4.0),
                          calmer * rng.lognormal(-0.125, 0.5),
                          float(rng.uniform(0.8, 2.5)))
        if steered:
            plan = steer_and_advance(plan, summary, n, rng)
            fault = plan.state
        else:
            fault = advance_fault(fault, summary, rng)
        n += 1
    return n - 100


@pytest.mark.parametrize(("mode", "position"), [("TTS", "WT"), ("MTEL", "WT"),
                                                ("MTWEAR", "WL1"), ("REWEAR", "WL2")])
def test_a_steered_fault_fails_at_the_planned_flight_on_flights_unlike_the_reference(
        mode: str, position: str) -> None:
    span = 60
    steered = [_fly(mode, position, span, steered=True, colder_k=12.0, calmer=0.6, seed=s)
               for s in range(8)]
    fixed = [_fly(mode, position, span, steered=False, colder_k=12.0, calmer=0.6, seed=s)
             for s in range(8)]
    assert max(abs(t - span) for t in steered) <= 0.1 * span, steered
    # the same flights with the rate fixed at onset miss the request by far
    assert np.median(fixed) > 1.3 * span, fixed


def test_each_flight_still_grows_the_fault_by_what_it_did() -> None:
    """Two flights with the same plan: the hotter one ages the winding more (TTS's law)."""
    fault, plan = plan_fault("TTS", "WT", np.random.default_rng(0), reference=_REF,
                             start_flight=1, span_flights=100.0)
    grown = {}
    for hotter in (0.0, 20.0):
        after = steer_and_advance(plan, _flight("WT", hotter, 1.0, 1.5), 1,
                                  np.random.default_rng(5))
        grown[hotter] = after.state.severity - fault.severity
    ratio = grown[20.0] / grown[0.0]
    d = {k: driver("TTS", _flight("WT", k, 1.0, 1.5).actuators["WT"], 1.5) for k in grown}
    # the flight's own driver sets its growth (the plan's mean driver moves a little with it)
    assert ratio == pytest.approx(d[20.0] / d[0.0], rel=0.5) and ratio > 2.0


def test_an_abrupt_fault_has_no_plan() -> None:
    fault, plan = plan_fault("BDO", "WT", np.random.default_rng(0), reference=_REF,
                             start_flight=1)
    assert plan is None and fault.mode == "BDO"


def _fly_season(base: str | None, *, start: int, span: int, seed: int) -> tuple[int, list[float]]:
    """A TTS fault at Turin steered over flights whose winding temperature follows the
    season (the reference is the annual mean); the flights it took and its rate per flight."""
    rng = np.random.default_rng(seed)
    fault, plan = plan_fault("TTS", "WT", rng, reference=_REF, start_flight=start,
                             span_flights=float(span), base=base)
    season = seasonal_offset_c("Turin", days_of_year(np.arange(start, start + 3 * span)))
    rates, n = [], start
    while not fault.failed and n < start + 3 * span:
        plan = steer_and_advance(plan, _flight("WT", season[n - start] + rng.normal(0.0, 2.0),
                                               1.0, 1.5), n, rng)
        fault = plan.state
        rates.append(fault.rate)
        n += 1
    return n - start, rates


def test_a_steered_thermal_fault_follows_the_season_and_still_fails_on_time() -> None:
    """From mid-August to October at Turin the flights cool by about 10 K: followed, the rate
    constant holds while the fault slows with the season, as a campaign's fault does; with
    every flight to come expected at the flights' mean so far, the rate climbs flight after
    flight to hold the summer's pace (the law the prognosis learned no longer holds)."""
    start, span = 454, 148  # flight 454: mid-August at two flights a day from 1 January
    for seed in range(4):
        took, rates = _fly_season("Turin", start=start, span=span, seed=seed)
        flat_took, flat_rates = _fly_season(None, start=start, span=span, seed=seed)
        assert abs(took - span) <= 0.1 * span and abs(flat_took - span) <= 0.1 * span
        q = len(rates) // 4
        drift = np.median(rates[-q:]) / np.median(rates[:q])
        flat_drift = np.median(flat_rates[-q:]) / np.median(flat_rates[:q])
        assert 0.8 < drift < 1.25 and flat_drift > 1.5, (drift, flat_drift)


def test_the_season_offset_is_the_climate_less_its_annual_mean() -> None:
    mean, _ = monthly_climate("Turin")
    mid_july = (6 + 0.5) * 365.25 / 12
    assert seasonal_offset_c("Turin", mid_july) == pytest.approx(mean[6] - mean.mean())
    # continuous over the new year
    assert seasonal_offset_c("Turin", 365.2) == pytest.approx(seasonal_offset_c("Turin", 0.0),
                                                             abs=0.05)
