"""The generic RUL interface cannot mislead: defaults stated, inputs checked with specific
messages, a backtest that sees only the past, quantiles by fraction or percent."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from server.phm.prognosis import (
    PriorDominatedWarning,
    PrognoserConfig,
    backtest_rul,
    predict_rul,
    track_rul,
)


def _capacity(n: int = 120, life: int = 150, seed: int = 8) -> np.ndarray:
    """A capacity fading linearly from 1.8 to its threshold 1.4 over ``life`` steps."""
    rng = np.random.default_rng(seed)
    k = np.arange(n)
    return 1.8 - 0.4 * k / life + 0.005 * rng.standard_normal(n)


def test_without_a_baseline_the_first_samples_are_the_healthy_level() -> None:
    x = _capacity()
    dist = predict_rul(x, 1.4, rng=3)  # no baseline: median of the first five samples
    true_rul = 150 - 119
    assert abs(dist.median - true_rul) <= 0.3 * true_rul
    assert dist.median == predict_rul(x, 1.4, baseline=float(np.median(x[:5])), rng=3).median


def test_numpy_integer_seeds_are_seeds() -> None:
    x = _capacity()
    assert predict_rul(x, 1.4, rng=np.int64(3)).median == predict_rul(x, 1.4, rng=3).median
    with pytest.raises(ValueError, match="integer seed"):
        predict_rul(x, 1.4, rng=3.0)  # type: ignore[arg-type]


@pytest.mark.parametrize(("time", "message"), [
    (np.arange(120) + 0.5, "whole numbers"),
    (np.arange(119), "119 values for 120 samples"),
    (np.r_[np.arange(60), np.arange(60)], "strictly increasing"),
])
def test_bad_times_get_a_specific_message(time: np.ndarray, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        predict_rul(_capacity(), 1.4, time=time)


def test_time_and_its_aircraft_name_are_one_argument() -> None:
    x = _capacity()
    t = np.arange(120) * 2
    assert predict_rul(x, 1.4, time=t, rng=1).median == \
        predict_rul(x, 1.4, flight_index=t, rng=1).median
    with pytest.raises(ValueError, match="not both"):
        predict_rul(x, 1.4, time=t, flight_index=t)


def test_too_few_samples_warn_that_the_prior_speaks() -> None:
    with pytest.warns(PriorDominatedWarning, match="3 samples"):
        predict_rul([1.80, 1.79, 1.78], 1.4, baseline=1.8)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        predict_rul(_capacity(), 1.4)  # enough samples: no warning


def test_a_backtest_sees_only_the_prefix() -> None:
    x = _capacity(n=140)
    # the last 40 samples are much noisier: track_rul's noise estimate sees them, a backtest
    # at t = 99 must not
    noisy = x.copy()
    noisy[100:] += 0.05 * np.random.default_rng(1).standard_normal(40)
    (bt,) = backtest_rul(noisy, 1.4, at=[99], rng=2)
    prefix = predict_rul(noisy[:100], 1.4, rng=2)
    assert bt.quantiles == prefix.quantiles
    # track_rul's answer at the same instant moves with the future's noise, the backtest's not
    (seen_future,), _ = track_rul(noisy, 1.4, predict_at=[99], rng=2)
    assert seen_future.quantiles != bt.quantiles
    (same,) = backtest_rul(np.r_[noisy, np.full(10, 9.9)], 1.4, at=[99], rng=2)
    assert same.quantiles == bt.quantiles
    with pytest.raises(ValueError, match="no sample at time 1000"):
        backtest_rul(noisy, 1.4, at=[1000])


def test_quantiles_by_fraction_or_percent() -> None:
    dist = predict_rul(_capacity(), 1.4, rng=3)
    assert dist.percentile(5) == dist.quantile(0.05) == dist.quantiles[0.05]
    assert dist.quantiles[0.25] <= dist.quantile(0.3) <= dist.quantiles[0.75]
    assert 0.0 <= dist.p_beyond_horizon <= 1.0
    with pytest.raises(ValueError, match="percentile"):
        dist.quantile(5)


def test_whole_numbers_given_as_floats_are_counts() -> None:
    cfg = PrognoserConfig(n_particles=500.0, max_horizon_flights=2000.0,  # type: ignore[arg-type]
                          pof_horizons_flights=(10.0, 25))  # type: ignore[arg-type]
    assert cfg.n_particles == 500 and isinstance(cfg.n_particles, int)
    assert cfg.pof_horizons_flights == (10, 25)
    for bad in (500.5, True, "500"):
        with pytest.raises(ValueError, match="whole number"):
            PrognoserConfig(n_particles=bad)  # type: ignore[arg-type]
