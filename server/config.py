"""Service configuration, read from the environment (prefix ``HMSM_``) by pydantic-settings.

Nothing is read at import time: :func:`load_settings` builds a fresh :class:`Settings` each call,
and the app factory takes the settings object it is given.
"""

from __future__ import annotations

from pathlib import Path

from pydantic import Field, field_validator
from pydantic_settings import BaseSettings, SettingsConfigDict

__all__ = ["Settings", "load_settings"]


class Settings(BaseSettings):
    """HMSM settings. Every field can be set as ``HMSM_<NAME>`` in the environment."""

    model_config = SettingsConfigDict(env_prefix="HMSM_", extra="ignore")

    data_dir: Path = Field(Path("./var"), description="Blobs, temporary uploads, SQLite file.")
    database_url: str | None = Field(
        None, description="SQLAlchemy URL; default: SQLite file hmsm.sqlite3 under data_dir."
    )
    max_upload_bytes: int = Field(64 * 1024 * 1024, gt=0, description="Largest request body [B].")
    host: str = Field("127.0.0.1", description="Bind address of `hmsm serve`.")
    port: int = Field(8000, ge=0, le=65535, description="TCP port of `hmsm serve`.")
    signals_max_points: int = Field(5000, gt=10, description="Cap on points per plotted channel.")

    @field_validator("data_dir")
    @classmethod
    def _absolute(cls, value: Path) -> Path:
        return value.expanduser().resolve()

    @property
    def effective_database_url(self) -> str:
        if self.database_url:
            url = self.database_url
            # psycopg 3 is the driver we ship; plain postgresql:// would ask for psycopg2.
            if url.startswith("postgresql://"):
                url = "postgresql+psycopg://" + url[len("postgresql://"):]
            return url
        return f"sqlite:///{self.data_dir / 'hmsm.sqlite3'}"

    @property
    def is_sqlite(self) -> bool:
        return self.effective_database_url.startswith("sqlite")

    @property
    def blob_dir(self) -> Path:
        return self.data_dir / "blobs"

    @property
    def tmp_dir(self) -> Path:
        return self.data_dir / "tmp"


def load_settings(**overrides: object) -> Settings:
    """Settings from the environment, with explicit keyword overrides on top."""
    return Settings(**overrides)  # type: ignore[arg-type]
