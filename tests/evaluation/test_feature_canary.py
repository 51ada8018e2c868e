"""The canary digest that keys stored features: the same for the same feature outputs, moved
by a change that moves a feature."""

from __future__ import annotations

from server.feature_canary import _DIGESTS, canary_digest
from server.phm.features import FeatureConfig


def test_the_digest_is_the_features_not_the_process() -> None:
    first = canary_digest()
    _DIGESTS.clear()  # computed again from the flights, not read back
    assert canary_digest() == first


def test_a_change_that_moves_features_moves_the_digest() -> None:
    # a shorter smoothing constant moves every EWMA-smoothed feature on every canary
    assert canary_digest(FeatureConfig(ewma_tau_s=2.5)) != canary_digest()
