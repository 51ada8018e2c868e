"""Where a campaign lives: a local directory, or an S3 prefix (``s3://bucket/prefix``) that a
Dask cluster's workers and the client write to without sharing any filesystem.

One small interface over :mod:`pyarrow.fs` (already a dependency, for Parquet), used by the
campaign's writers (:mod:`sim_worker.campaign`, ``server.campaigns.FeatureSink``) and its
readers (``server.campaigns``, ``hmsm evaluate`` / ``train``): files named by their path
relative to the campaign (``manifest.json``, ``flights/<tail>/<flight>.parquet``). A leaf
beside ``server.flightlog`` (pyarrow only, contract in pyproject's ``[tool.importlinter]``):
the simulator may import it, and the service need not import the simulator to read a campaign;
the service's own blob store (boto3, ``server.blobstore_s3``) stays out of the simulator.

pyarrow rather than boto3: the same calls reach a local directory and a bucket, and the
Parquet footer of a flight log is read with a ranged GET instead of the whole object.
Credentials come from the standard AWS_* environment variables of each process (client and
every worker); a store other than AWS S3 is reached at ``endpoint`` (``HMSM_S3_ENDPOINT_URL``).
A :class:`CampaignStore` is a plain value: pickled to the workers, each opens its own client.
"""

from __future__ import annotations

import os
import re
import threading
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

__all__ = ["CampaignStore", "S3_URL", "ENDPOINT_URL", "ENDPOINT_ENV"]

#: an S3 location: bucket (3-63 of a-z 0-9 . -), then an optional prefix; HMSM_BLOB_URL's too
S3_URL = re.compile(r"s3://([a-z0-9][a-z0-9.-]{1,61}[a-z0-9])(/[A-Za-z0-9/_.\-]*)?")
#: the service's setting for a store other than AWS S3 (owned by ``server.config.Settings``),
#: read by name by the ``sim-worker`` script, which may not import the service's settings
ENDPOINT_ENV = "HMSM_S3_ENDPOINT_URL"
#: an S3 server's URL (HMSM_S3_ENDPOINT_URL): http(s)://host[:port]
ENDPOINT_URL = re.compile(r"https?://[^\s/?#]+/?")


@dataclass(frozen=True)
class CampaignStore:
    """A campaign's location: ``root`` is an absolute directory, or ``bucket/prefix`` when
    ``remote``; ``endpoint`` the S3 server's URL (None: AWS S3)."""

    root: str
    remote: bool = False
    endpoint: str | None = None

    @classmethod
    def at(cls, location: str | os.PathLike[str] | CampaignStore,
           endpoint: str | None = None) -> CampaignStore:
        """The store at ``location``, a directory or ``s3://bucket[/prefix]``; a malformed
        S3 URL or endpoint is a ValueError that says what is expected."""
        if isinstance(location, CampaignStore):
            return location
        text = os.fspath(location)
        if not text.startswith("s3:"):
            return cls(str(Path(text).expanduser().resolve()))
        match = S3_URL.fullmatch(text)
        if match is None:
            raise ValueError(f"{text}: an S3 location is s3://bucket or s3://bucket/prefix "
                             "(bucket: 3-63 of a-z 0-9 . -; prefix: letters, digits, / _ . -)")
        if endpoint is not None and not ENDPOINT_URL.fullmatch(endpoint):
            raise ValueError(f"{ENDPOINT_ENV} must be http(s)://host[:port], got {endpoint!r}")
        prefix = (match.group(2) or "").strip("/")
        return cls(f"{match.group(1)}/{prefix}".rstrip("/"), remote=True, endpoint=endpoint)

    def __str__(self) -> str:
        return f"s3://{self.root}" if self.remote else self.root

    def child(self, name: str) -> CampaignStore:
        """The store at ``name`` below this one (a protocol run's ``design/``)."""
        return CampaignStore(f"{self.root}/{name}", self.remote, self.endpoint)

    def local_dir(self) -> Path | None:
        """The directory of a local store (None for S3)."""
        return None if self.remote else Path(self.root)

    def check(self) -> None:
        """ValueError, saying why, unless an S3 store's bucket exists and answers: before hours
        of simulation rather than at the first file written."""
        if not self.remote:
            return
        from pyarrow import fs

        bucket = self.root.split("/", 1)[0]
        try:
            found = self._fs().get_file_info(bucket).type == fs.FileType.Directory
        except OSError as exc:
            raise ValueError(f"{self}: the object store does not answer ({exc})") from None
        if not found:
            raise ValueError(f"{self}: no bucket {bucket!r} at "
                             f"{self.endpoint or 'AWS S3'}; create it first")

    def _fs(self) -> Any:
        return _s3(self.endpoint) if self.remote else _local()

    def _path(self, rel: str) -> str:
        return f"{self.root}/{rel}"

    def exists(self, rel: str) -> bool:
        from pyarrow import fs

        return bool(self._fs().get_file_info(self._path(rel)).type == fs.FileType.File)

    def read(self, rel: str) -> bytes:
        """The file's bytes; FileNotFoundError when there is none."""
        with self._fs().open_input_file(self._path(rel)) as f:
            return bytes(f.read())

    def read_text(self, rel: str) -> str | None:
        """The file as text, None when there is none."""
        try:
            return self.read(rel).decode()
        except FileNotFoundError:
            return None

    def open(self, rel: str) -> Any:
        """A seekable reader of the file (a Parquet footer is read without the rest)."""
        return self._fs().open_input_file(self._path(rel))

    def write(self, rel: str, data: bytes) -> None:
        """Write ``data``; a reader sees the whole file or none of it (S3 shows an object only
        once its upload completes; a local file is renamed into place)."""
        if self.remote:
            with self._fs().open_output_stream(self._path(rel)) as f:
                f.write(data)
            return
        path = Path(self._path(rel))
        path.parent.mkdir(parents=True, exist_ok=True)
        # a name of this writer's own: two processes writing one file (two evaluations
        # caching a campaign's features at once) must not rename each other's part away
        tmp = path.with_name(f"{path.name}.{os.getpid()}.{threading.get_ident()}.tmp")
        tmp.write_bytes(data)
        os.replace(tmp, path)

    def remove_dir(self, rel: str) -> None:
        """Remove the directory ``rel`` and everything below it."""
        self._fs().delete_dir(self._path(rel))


@lru_cache(maxsize=1)
def _local() -> Any:
    from pyarrow import fs

    return fs.LocalFileSystem()


def _s3(endpoint: str | None) -> Any:
    # one client per process: a pool's forked child opens its own
    return _s3_client(endpoint, os.getpid())


@lru_cache(maxsize=4)
def _s3_client(endpoint: str | None, pid: int) -> Any:
    from pyarrow import fs

    if endpoint is None:
        return fs.S3FileSystem()
    scheme, host = endpoint.rstrip("/").split("://", 1)
    return fs.S3FileSystem(endpoint_override=host, scheme=scheme)
