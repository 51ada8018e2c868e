"""Fixtures of the simulator tests."""

from __future__ import annotations

import pytest

from sim_worker.fleet import Aircraft, build_aircraft


@pytest.fixture(scope="session")
def aircraft() -> Aircraft:
    return build_aircraft("I-TEST01", "Turin", seed=12345)
