"""Database engine and sessions (SQLAlchemy 2.0).

SQLite runs in WAL mode with a busy timeout so the API threads and workers can write to the
same file; PostgreSQL is used as is. Engines are built by :func:`make_engine`, never at import.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from typing import TypeAlias

from sqlalchemy import Engine, create_engine, event, text
from sqlalchemy.exc import SQLAlchemyError
from sqlalchemy.orm import Session, sessionmaker

__all__ = ["SessionFactory", "make_engine", "make_session_factory", "session_scope",
           "DatabaseUnavailable", "unavailable_on_error", "ping"]

#: what opens a session (``app.state.session_factory``): callers outside the services name
#: its type by this, without importing SQLAlchemy
SessionFactory: TypeAlias = sessionmaker[Session]


def make_engine(url: str) -> Engine:
    if url.startswith("sqlite"):
        engine = create_engine(url, connect_args={"timeout": 30, "check_same_thread": False})

        @event.listens_for(engine, "connect")
        def _sqlite_pragmas(dbapi_conn, _record):
            cur = dbapi_conn.cursor()
            cur.execute("PRAGMA journal_mode=WAL")
            cur.execute("PRAGMA foreign_keys=ON")
            cur.execute("PRAGMA busy_timeout=30000")
            cur.close()

        return engine
    return create_engine(url, pool_pre_ping=True, pool_size=10, max_overflow=20)


def make_session_factory(engine: Engine) -> SessionFactory:
    return sessionmaker(engine, expire_on_commit=False)


@contextmanager
def session_scope(factory: SessionFactory) -> Iterator[Session]:
    """One unit of work: commit on success, roll back on any error."""
    session = factory()
    try:
        yield session
        session.commit()
    except BaseException:
        session.rollback()
        raise
    finally:
        session.close()


class DatabaseUnavailable(Exception):
    """The database did not answer: SQLAlchemy's error, in a name the routes may import (the
    API is kept from importing SQLAlchemy by a contract in pyproject.toml)."""


@contextmanager
def unavailable_on_error() -> Iterator[None]:
    """Any SQLAlchemy error in the block raised as :class:`DatabaseUnavailable`."""
    try:
        yield
    except SQLAlchemyError as exc:
        raise DatabaseUnavailable(str(exc)) from exc


def ping(engine: Engine) -> None:
    """Raise :class:`DatabaseUnavailable` unless the database answers a trivial query."""
    with unavailable_on_error(), engine.connect() as conn:
        conn.execute(text("SELECT 1"))
