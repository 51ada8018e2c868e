"""Schema migrations through Alembic: upgrade, downgrade, and the start-up check.

The embedded SQLite default upgrades itself at start; any other database that is behind makes
the service refuse to start with a message that names ``hmsm db upgrade``.
"""

from __future__ import annotations

from pathlib import Path

from alembic import command
from alembic.config import Config
from alembic.runtime.migration import MigrationContext
from alembic.script import ScriptDirectory
from sqlalchemy import Engine

__all__ = ["alembic_config", "upgrade", "downgrade", "head_revision", "current_revision",
           "SchemaBehindError", "ensure_schema"]

MIGRATIONS_DIR = Path(__file__).resolve().parent.parent / "migrations"


class SchemaBehindError(RuntimeError):
    """The database schema is not at the code's head revision."""


def alembic_config(url: str) -> Config:
    cfg = Config()
    cfg.set_main_option("script_location", str(MIGRATIONS_DIR))
    cfg.set_main_option("sqlalchemy.url", url.replace("%", "%%"))
    return cfg


def upgrade(url: str, revision: str = "head") -> None:
    command.upgrade(alembic_config(url), revision)


def downgrade(url: str, revision: str = "base") -> None:
    command.downgrade(alembic_config(url), revision)


def head_revision() -> str:
    head = ScriptDirectory.from_config(alembic_config("sqlite://")).get_current_head()
    if head is None:
        raise RuntimeError("the migrations directory holds no Alembic revision")
    return head


def current_revision(engine: Engine) -> str | None:
    with engine.connect() as conn:
        return MigrationContext.configure(conn).get_current_revision()


def ensure_schema(engine: Engine, url: str, *, auto_upgrade: bool) -> None:
    """Upgrade (embedded SQLite) or refuse to run on a schema that is behind."""
    if current_revision(engine) == head_revision():
        return
    if auto_upgrade:
        upgrade(url)
        return
    raise SchemaBehindError(
        f"The database schema is at revision {current_revision(engine) or 'none (empty)'}, "
        f"the code needs {head_revision()}. Run `hmsm db upgrade` (with the same "
        "HMSM_DATABASE_URL) and start again."
    )
