"""A session factory on a migrated database of the chosen backend, for the jobs tests."""

from __future__ import annotations

import pytest

from server.config import Settings
from server.db import make_engine, make_session_factory
from server.migrate import upgrade


@pytest.fixture
def factory(settings: Settings):  # type: ignore[no-untyped-def]
    settings.data_dir.mkdir(parents=True, exist_ok=True)
    upgrade(settings.effective_database_url)
    engine = make_engine(settings.effective_database_url)
    yield make_session_factory(engine)
    engine.dispose()
