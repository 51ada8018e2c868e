"""Alembic: upgrade from empty, downgrade to base, and no drift between models and migrations."""

from __future__ import annotations

from alembic.autogenerate import compare_metadata
from alembic.runtime.migration import MigrationContext
from sqlalchemy import create_engine, inspect

from server.config import Settings
from server.migrate import downgrade, head_revision, upgrade
from server.models import Base


def _fresh_url(settings: Settings) -> str:
    if settings.is_sqlite:
        settings.data_dir.mkdir(parents=True, exist_ok=True)
        return settings.effective_database_url
    url = settings.effective_database_url
    downgrade(url, "base")  # the session database starts at head
    return url


def test_upgrade_downgrade_and_no_drift(settings: Settings) -> None:
    url = _fresh_url(settings)
    engine = create_engine(url)
    upgrade(url)
    with engine.connect() as conn:
        ctx = MigrationContext.configure(conn)
        assert ctx.get_current_revision() == head_revision()
        diff = compare_metadata(ctx, Base.metadata)
    assert diff == [], f"models and migrations drift: {diff}"
    assert {"aircraft", "actuators", "flights", "jobs", "api_keys"} <= set(
        inspect(engine).get_table_names())

    downgrade(url, "base")
    engine.dispose()
    engine = create_engine(url)
    assert set(inspect(engine).get_table_names()) <= {"alembic_version"}
    upgrade(url)  # leave it at head for the next test on this database
    engine.dispose()
