"""The compiled sums, medians and means of the feature and quality loops give NumPy's bits."""

from __future__ import annotations

import numpy as np
import pytest

from server.phm.pairwise import pairwise_sum
from server.phm.signal_quality_loops import clipped_mean_square, sparse_abs_median

LENGTHS = [0, 1, 7, 8, 9, 127, 128, 129, 130, 255, 256, 257, 1000, 1031, 4096, 99_999, 200_003]


@pytest.mark.parametrize("n", LENGTHS)
def test_the_pairwise_sum_is_numpys(n: int) -> None:
    rng = np.random.default_rng(n)
    a = rng.normal(size=n) * rng.uniform(0.0, 1e3, size=n)
    assert pairwise_sum(a) == np.sum(a)


def test_the_pairwise_sum_of_negative_zeros_is_positive_zero_as_numpys() -> None:
    a = np.full(300, -0.0)
    assert np.signbit(np.sum(a)) == np.signbit(pairwise_sum(a))


@pytest.mark.parametrize("n", [1, 2, 3, 4, 5, 8, 801, 4000, 4001, 30_000])
def test_the_median_and_clipped_power_are_numpys(n: int) -> None:
    rng = np.random.default_rng(n)
    d2 = np.round(rng.normal(size=n) * 4.0) * 0.05  # quantised: ties in the median
    d2[:: 97] = 50.0  # spikes to clip
    assert sparse_abs_median(d2, 4) == np.median(np.abs(d2[::4]))
    limit = 0.3
    clipped = np.clip(d2, -limit, limit)
    assert clipped_mean_square(d2, limit) == np.mean(clipped * clipped)
