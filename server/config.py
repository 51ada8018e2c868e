"""Service configuration, read from the environment (prefix ``HMSM_``) by pydantic-settings.

Nothing is read at import time: :func:`load_settings` builds a fresh :class:`Settings` each call,
and the app factory takes the settings object it is given.
"""

from __future__ import annotations

from dataclasses import fields
from pathlib import Path
from typing import Any

from pydantic import Field, SecretStr, field_validator, model_validator
from pydantic_settings import BaseSettings, SettingsConfigDict

from server.campaign_store import ENDPOINT_URL, S3_URL
from server.flightlog import DecodeLimits

__all__ = ["SQLITE_FILE_NAME", "Settings", "load_settings"]

#: the embedded default database's file under the data directory
SQLITE_FILE_NAME = "hmsm.sqlite3"

_DECODE = DecodeLimits()


class Settings(BaseSettings):
    """HMSM settings. Every field can be set as ``HMSM_<NAME>`` in the environment."""

    model_config = SettingsConfigDict(env_prefix="HMSM_", extra="ignore")

    data_dir: Path = Field(Path("./var"), description="Blobs, temporary uploads, SQLite file.")
    database_url: str | None = Field(
        None, description=f"SQLAlchemy URL; default: SQLite file {SQLITE_FILE_NAME} under data_dir."
    )
    max_upload_bytes: int = Field(64 * 1024 * 1024, gt=0, description="Largest request body [B].")
    host: str = Field("127.0.0.1", description="Bind address of `hmsm serve`.")
    port: int = Field(8000, ge=0, le=65535, description="TCP port of `hmsm serve`.")
    signals_max_points: int = Field(5000, gt=10, description="Cap on points per plotted channel.")
    signals_concurrency: int = Field(2, ge=1, description=(
        "Signal reads (`GET /flights/{id}/signals`) decoded at once, each on a thread of their "
        "own pool (docs/SECURITY.md: memory per read)."))
    signals_waiting: int = Field(64, ge=0, description=(
        "Signal reads that may wait for those; past that 503 `busy` with Retry-After."))
    # What a decoder may build from an upload (server.flightlog.DecodeLimits, which gives the
    # defaults and why; docs/SECURITY.md, "Hostile uploads")
    max_decompressed_bytes: int = Field(_DECODE.max_decompressed_bytes, gt=0, description=(
        "Largest gzip CSV text after decompression [B]."))
    max_samples_per_channel: int = Field(_DECODE.max_samples_per_channel, gt=0, description=(
        "Most samples per channel of one flight log (default 12 h at 800 Hz)."))
    max_decoded_bytes: int = Field(_DECODE.max_decoded_bytes, gt=0, description=(
        "Largest size of a flight log's channels once decoded [B]."))
    max_columns: int = Field(_DECODE.max_columns, gt=0, description=(
        "Most columns (CSV, Parquet) or variables (MAT) of one flight log."))
    max_line_chars: int = Field(_DECODE.max_line_chars, gt=0, description=(
        "Longest CSV line, header or row [characters]."))
    max_footer_bytes: int = Field(_DECODE.max_footer_bytes, gt=0, description=(
        "Largest Parquet footer (schema, row groups, key-value metadata) [B]."))
    max_metadata_chars: int = Field(_DECODE.max_metadata_chars, gt=0, description=(
        "Longest flight metadata value (form field, Parquet or MAT metadata) [characters]."))
    max_json_depth: int = Field(_DECODE.max_json_depth, gt=0, description=(
        "Deepest JSON nesting of actuator_serials."))
    max_reason_chars: int = Field(_DECODE.max_reason_chars, ge=256, description=(
        "Largest rejection reason stored and echoed, as JSON [characters]."))
    max_reasons: int = Field(_DECODE.max_reasons, ge=2, description=(
        "Most rejection reasons stored and echoed per flight."))
    keep_alive_s: int = Field(5, ge=1, le=300, description=(
        "`hmsm serve` closes a keep-alive connection idle this long [s]."))
    max_connections: int = Field(200, ge=8, description=(
        "`hmsm serve` answers 503 beyond this many open connections or requests, which bounds "
        "what slow clients can hold (uvicorn has no header timeout)."))
    body_idle_timeout_s: float = Field(30.0, gt=0, le=3600, description=(
        "A request body that sends nothing for this long is cut with 408 [s]."))
    auth_failures_per_minute: int = Field(20, ge=0, description=(
        "Failed authentications (wrong or revoked key: API, session cookie or sign-in form) "
        "one presented key, and separately one client address, may make in a burst, and again "
        "each minute. Past a key's budget that key is answered 429 with Retry-After; past an "
        "address's, its wrong keys are (a right key is always served). 0: no limit."))
    auth_failure_clients: int = Field(10_000, ge=1, description=(
        "Most client addresses whose failed authentications are tracked; past that the one "
        "that failed least recently is forgotten."))
    auth_failure_keys: int = Field(10_000, ge=1, description=(
        "Most presented keys whose failed authentications are tracked (by their SHA-256); "
        "past that the one that failed least recently is forgotten."))
    train_disk_reserve_bytes: int = Field(1024 ** 3, ge=0, description=(
        "Free disk a design campaign generated for training (`POST /api/v1/models/train` with "
        "`generate`) must leave besides its own size; less: 507 `insufficient_storage`."))
    raw_retention_flights: int | None = Field(None, ge=0, description=(
        "Keep the raw logs of only this many most recent analysed flights per aircraft, healthy "
        "or in alarm, and of the flights that raised an alarm or made one of its last 4 class "
        "changes; the other "
        "analysed flights' logs are removed after each analysis, their features and results "
        "kept (server/services/retention.py). Unset: every raw log is kept (the default)."))

    rejected_bytes_per_key: int = Field(128 * 1024 * 1024, ge=0, description=(
        "Most bytes of rejected flight logs kept for one API key (distinct files, summed); a "
        "rejected file past it is not kept: 507 `rejected_quota_exceeded` with its reasons. "
        "0: none kept."))
    blob_url: str | None = Field(None, description=(
        "Where flight logs are kept: `s3://bucket/prefix` for an S3-compatible object store "
        "(credentials from the standard AWS_* environment variables), shared by every API "
        "process and worker; unset: `blobs` under data_dir."))
    s3_endpoint_url: str | None = Field(None, description=(
        "The object store's URL (`http://seaweedfs:8333`) when it is not AWS S3 itself; "
        "path-style addressing is used then."))
    # A store that accepts connections and never answers must cost an upload less than a
    # client waits (60 s is common), or the client sees a dropped connection instead of a 503
    # and the upload holds one of HMSM_MAX_CONNECTIONS all along
    blob_store_connect_timeout_s: float = Field(2.0, gt=0, le=60, description=(
        "One request to the object store (HMSM_BLOB_URL) may take this long to connect [s]."))
    blob_store_read_timeout_s: float = Field(5.0, gt=0, le=300, description=(
        "One request to the object store waits this long for the next bytes of its answer "
        "before it fails and is tried again, deadline permitting [s]."))
    blob_store_deadline_s: float = Field(15.0, gt=0, le=600, description=(
        "Longest one operation on the object store may take, its tries included (an upload's "
        "store, a log read, one listing page): no try starts that could not end within it "
        "(connect and read timeouts, and the backoff before it), so an upload to a store that "
        "does not answer gets 503 `storage_unreachable` with Retry-After within it, and a "
        "worker defers the job. Keep it under the clients' timeout [s]."))
    blob_store_probe_timeout_s: float = Field(1.0, gt=0, le=30, description=(
        "The readiness probe's one request to the object store (GET /api/v1/health/ready): "
        "its connect and its answer each within this; no answer: not ready [s]."))
    metrics_token: SecretStr | None = Field(None, description=(
        "Bearer token that may read GET /metrics (besides an admin key): at least 32 "
        "characters, no spaces. Unset: only admin keys may."))
    metrics_token_file: Path | None = Field(None, description=(
        "A file holding the metrics token (a compose or Kubernetes secret), read at start; "
        "instead of HMSM_METRICS_TOKEN."))

    @model_validator(mode="after")
    def _metrics_token_from_file(self) -> Settings:
        if self.metrics_token_file is not None:
            if self.metrics_token is not None:
                raise ValueError("set HMSM_METRICS_TOKEN or HMSM_METRICS_TOKEN_FILE, not both")
            try:
                text = self.metrics_token_file.read_text(encoding="utf-8").strip()
            except (OSError, UnicodeDecodeError) as exc:
                raise ValueError(f"HMSM_METRICS_TOKEN_FILE: cannot read "
                                 f"{self.metrics_token_file}: {exc}") from None
            self.metrics_token = SecretStr(text)
        if self.metrics_token is not None:
            _check_metrics_token(self.metrics_token.get_secret_value())
        return self

    @model_validator(mode="after")
    def _store_deadline_fits_a_try(self) -> Settings:
        try_s = self.blob_store_connect_timeout_s + self.blob_store_read_timeout_s
        if self.blob_store_deadline_s < try_s:
            raise ValueError(f"HMSM_BLOB_STORE_DEADLINE_S ({self.blob_store_deadline_s:g} s) "
                             f"must leave time for one try: at least the connect and read "
                             f"timeouts together ({try_s:g} s)")
        return self

    @field_validator("blob_url")
    @classmethod
    def _s3_url(cls, value: str | None) -> str | None:
        if value is not None and not S3_URL.fullmatch(value):
            raise ValueError("HMSM_BLOB_URL must be s3://bucket or s3://bucket/prefix (bucket: "
                             "3-63 of a-z 0-9 . -; prefix: letters, digits, / _ . -)")
        return value

    @field_validator("s3_endpoint_url")
    @classmethod
    def _endpoint(cls, value: str | None) -> str | None:
        if value is not None and not ENDPOINT_URL.fullmatch(value):
            raise ValueError("HMSM_S3_ENDPOINT_URL must be http(s)://host[:port]")
        return value

    @property
    def blob_bucket(self) -> tuple[str, str]:
        """``(bucket, prefix)`` of HMSM_BLOB_URL; the prefix without slashes at its ends."""
        if self.blob_url is None:
            raise ValueError("HMSM_BLOB_URL is not set")
        bucket, _, prefix = self.blob_url[len("s3://"):].partition("/")
        return bucket, prefix.strip("/")

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
        return f"sqlite:///{self.sqlite_file}"

    @property
    def sqlite_file(self) -> Path:
        """The embedded default database's file (used when no ``database_url`` is set)."""
        return self.data_dir / SQLITE_FILE_NAME

    @property
    def is_sqlite(self) -> bool:
        return self.effective_database_url.startswith("sqlite")

    @property
    def decode_limits(self) -> DecodeLimits:
        """The flight-log readers' limits from these settings."""
        return DecodeLimits(**{f.name: getattr(self, f.name) for f in fields(DecodeLimits)})

    def server_options(self) -> dict[str, Any]:
        """uvicorn's limits for `hmsm serve` (and the demo)."""
        return {"timeout_keep_alive": self.keep_alive_s,
                "limit_concurrency": self.max_connections,
                "h11_max_incomplete_event_size": 16 * 1024}  # request line + headers [B]

    @property
    def blob_dir(self) -> Path:
        return self.data_dir / "blobs"

    @property
    def tmp_dir(self) -> Path:
        return self.data_dir / "tmp"


#: the shortest metrics token accepted: 32 characters (128 bits as hex) cannot be guessed at
#: any request rate (the failed-authentication limit never refuses the right token)
METRICS_TOKEN_MIN_CHARS = 32


def _check_metrics_token(token: str) -> None:
    """A token long enough not to be guessed, of visible ASCII (it travels in a header)."""
    if len(token) < METRICS_TOKEN_MIN_CHARS or len(token) > 512:
        raise ValueError(f"the metrics token must have {METRICS_TOKEN_MIN_CHARS} to 512 "
                         "characters (e.g. `openssl rand -hex 32`)")
    if not all("!" <= c <= "~" for c in token):
        raise ValueError("the metrics token must be visible ASCII, without spaces")


def load_settings(**overrides: object) -> Settings:
    """Settings from the environment, with explicit keyword overrides on top."""
    return Settings(**overrides)  # type: ignore[arg-type]
