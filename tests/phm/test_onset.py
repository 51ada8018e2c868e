"""Change point of a fault's growth (server.phm.prognosis.onset)."""

from __future__ import annotations

import numpy as np
import pytest

from server.phm.prognosis import growth_onset


@pytest.mark.parametrize("onset, step", [(60, 5), (200, 5), (68, 20)])
def test_growth_onset_finds_where_a_wear_line_leaves_the_healthy_flat(onset: int,
                                                                     step: int) -> None:
    """Severity 0 before the onset, a 0.05 step and 1/250 per flight after it, measured with a
    sigma of 0.02 (F_MTWEAR's is 0.017): the onset is found within one measurement."""
    rng = np.random.default_rng(onset)
    k = np.arange(0, 400, step)
    true = np.where(k >= onset, 0.05 + (k - onset) / 250.0, 0.0)
    found = growth_onset(k, true + 0.02 * rng.standard_normal(k.size))
    assert abs(found - onset) <= step


def test_growth_onset_of_a_fault_growing_from_the_start_is_the_first_flight() -> None:
    k = np.arange(10, 200, 10)
    assert growth_onset(k, 0.1 + (k - 10) / 200.0) == 10


def test_growth_onset_with_too_few_points_is_the_first_and_bad_input_is_refused() -> None:
    assert growth_onset([7, 9], [0.3, 0.4]) == 7
    with pytest.raises(ValueError):
        growth_onset([3, 2, 5], [0.0, 0.1, 0.2])
    with pytest.raises(ValueError):
        growth_onset([1, 2, 3], [0.0, np.nan, 0.2])
    with pytest.raises(ValueError):
        growth_onset([1, 2, 3], [0.0, 0.1])
