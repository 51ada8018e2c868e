"""Seasonal stress clock (server.phm.season) and the prognoser running on it."""

from __future__ import annotations

import math
from datetime import UTC, datetime, timedelta

import numpy as np
import pytest

from server.phm.prognosis import MeasurementModel, ParticleFilterPrognoser, PrognoserConfig
from server.phm.season import (
    SEASON_DEFAULTS,
    SeasonalClimate,
    SeasonConfig,
    StressClock,
    day_of_year,
    next_flights_per_day,
)

OMEGA = 2.0 * math.pi / 365.25


def _climate() -> SeasonalClimate:
    return SeasonalClimate({"Turin": (13.0, -10.0, 0.0)})  # 3 degC in January, 23 in July


def test_climate_fit_recovers_an_annual_cycle_from_noisy_flights() -> None:
    rng = np.random.default_rng(3)
    days = rng.uniform(0, 365, 400)
    temps = 13.0 - 10.0 * np.cos(OMEGA * days) + 2.0 * np.sin(OMEGA * days) \
        + 4.0 * rng.standard_normal(days.size)
    bases = ["Turin"] * days.size + ["Nowhere"] * 5  # too few flights: no climate
    fit = SeasonalClimate.fit(bases, np.r_[days, np.zeros(5)], np.r_[temps, np.zeros(5)])
    assert set(fit.coefficients) == {"Turin"}
    np.testing.assert_allclose(fit.coefficients["Turin"], (13.0, -10.0, 2.0), atol=0.6)
    again = SeasonalClimate.from_dict(fit.to_dict())
    assert again == fit
    with pytest.raises(ValueError):
        SeasonalClimate.from_dict({"Turin": [1.0, 2.0]})


def test_day_of_year_is_fractional_from_new_year() -> None:
    assert day_of_year(datetime(2025, 1, 1, tzinfo=UTC)) == 0.0
    assert day_of_year(datetime(2025, 2, 1, 12, tzinfo=UTC)) == pytest.approx(31.5)


def test_stress_clock_runs_fast_in_summer_and_sums_consistently() -> None:
    beta = math.log(2.0) / 10.0  # life halves per +10 K
    winter = StressClock(_climate(), "Turin", beta, None, datetime(2025, 1, 1, tzinfo=UTC), 0,
                         2.0)
    summer = StressClock(_climate(), "Turin", beta, None, datetime(2025, 7, 2, tzinfo=UTC), 0,
                         2.0)
    # 10 K below / above the annual mean: half / twice a reference flight
    assert winter.between(0, 10) == pytest.approx(5.0, rel=0.02)
    assert summer.between(0, 10) == pytest.approx(20.0, rel=0.02)
    curve = winter.curve(0, 730)  # a full year at two flights a day
    assert curve[0] == 0.0 and np.all(np.diff(curve) > 0)
    assert curve[40] == pytest.approx(winter.between(0, 40), rel=0.01)
    # over a whole year the stress is the mean of exp(beta * 10 cos) times the flights
    mean_rate = np.mean(np.exp(beta * 10.0 * np.cos(np.linspace(0, 2 * np.pi, 10001))))
    assert curve[-1] == pytest.approx(730 * mean_rate, rel=0.01)
    flat = StressClock(_climate(), "Turin", 0.0, None, datetime(2025, 1, 1, tzinfo=UTC), 0, 2.0)
    assert flat.between(5, 25) == pytest.approx(20.0)


def test_season_settings_are_the_config_defaults() -> None:
    assert SEASON_DEFAULTS == SeasonConfig(min_flights_per_base=24, gap_points=16,
                                           flying_rate_weight=0.1)
    # a base with one flight fewer than the minimum gets no climate
    days = np.linspace(0, 360, SEASON_DEFAULTS.min_flights_per_base)
    temps = 13.0 - 10.0 * np.cos(OMEGA * days)
    assert SeasonalClimate.fit(["A"] * days.size, days, temps).knows("A")
    assert not SeasonalClimate.fit(["A"] * (days.size - 1), days[1:], temps[1:]).knows("A")


def test_flying_rate_is_an_exponentially_weighted_mean() -> None:
    assert next_flights_per_day(None, 20, timedelta(days=10)) == 2.0
    assert next_flights_per_day(2.0, 10, timedelta(days=10)) == pytest.approx(1.9)
    assert next_flights_per_day(2.0, 10, timedelta(days=10), weight=0.5) == 1.5
    assert next_flights_per_day(2.0, 0, timedelta(days=1)) == 2.0


def test_prognoser_on_a_stress_clock_maps_the_rul_back_to_flights() -> None:
    """A fault that grows on stress: with the season's clock the RUL in flights follows the
    coming warm months; on a flight clock the same filter assumes the past rate goes on."""
    model = MeasurementModel((0.0, 1.0), 0.01)
    cfg = PrognoserConfig(rate_basis="exponential", growth_offset=0.1, initial_theta=(0.0, 0.01),
                          rls_forgetting=1.0, process_noise_std=0.002)
    pf = ParticleFilterPrognoser(cfg, model)
    clock = StressClock(_climate(), "Turin", math.log(2.0) / 10.0, None,
                        datetime(2025, 1, 1, tzinfo=UTC), 0, 2.0)
    r = 0.012  # per unit of stress
    rng = np.random.default_rng(5)
    tau = clock.curve(0, 800)
    severity = 0.05 * np.exp(r * tau) + 0.1 * (np.exp(r * tau) - 1.0)  # ln(h + c) linear
    failure = int(np.searchsorted(severity, 1.0))
    state = flights_only = pf.initial_state(cfg, model, 1)
    for k in range(0, 120, 5):  # January to March
        z = severity[k] + 0.01 * rng.standard_normal()
        stress = None if state.flight_index is None else clock.between(state.flight_index, k)
        state = pf.update(state, z, k, stress=stress)
        flights_only = pf.update(flights_only, z, k)
    with_clock = pf.predict(state, stress_curve=clock.curve(state.flight_index, 2000))
    true_rul = failure - state.flight_index
    assert abs(with_clock.median - true_rul) / true_rul < 0.1
    assert with_clock.quantiles[0.05] <= true_rul <= with_clock.quantiles[0.95]
    # the same filter on flights learns the winter's rate and expects it to go on: too long
    on_flights = pf.predict(flights_only)
    assert on_flights.median > 1.2 * true_rul
    with pytest.raises(ValueError):
        pf.predict(state, stress_curve=np.array([0.0, 1.0, 1.0]))
    with pytest.raises(ValueError):
        pf.update(state, 0.5, 200, stress=-1.0)
