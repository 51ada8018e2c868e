"""Content-addressed storage of raw flight files: a local directory (the default) or an
S3-compatible object store (``HMSM_BLOB_URL=s3://bucket/prefix``, :mod:`server.blobstore_s3`).

Either way a body is first streamed to a temporary file in ``<data_dir>/tmp``, hashed as it
goes; :meth:`BlobStore.commit` then puts it in place under a key derived from the SHA-256 alone
(no client string reaches a path or key), so a reader never sees a half-written blob. Locally
the file is fsynced and renamed; in the object store it is one PUT (multipart past a part's
size, aborted on failure), which S3 makes visible whole or not at all. A crash leaves only a
temporary file (or an unfinished multipart upload), which :meth:`BlobStore.sweep_tmp` removes
at the next start. :func:`server.blobstore_factory.open_blob_store` builds the store the settings
name; this module imports neither it nor the object store.
"""

from __future__ import annotations

import hashlib
import os
import tempfile
import time
from abc import ABC, abstractmethod
from collections.abc import AsyncIterator, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

__all__ = ["BlobStore", "LocalBlobStore", "SpooledUpload", "StoredBlob", "BlobTooLarge",
           "BlobStoreUnreachable", "files_under", "TMP_MAX_AGE_S"]

_HEX = set("0123456789abcdef")
#: temporary files (and unfinished multipart uploads) older than this at start-up belong to
#: no live upload (one spools in seconds)
TMP_MAX_AGE_S = 10 * 60


class BlobTooLarge(Exception):
    """The stream went past the size limit; nothing was kept."""


class BlobStoreUnreachable(ConnectionError):
    """The object store did not answer, retries included: nothing was written; try later.
    A ConnectionError (so an OSError): code that treats any store failure alike still may."""


class StoredBlob(NamedTuple):
    """One object in the store: its file name (the SHA-256 for a blob we wrote), size [B] and
    when it was last written (Unix time; a commit of bytes already stored renews it)."""

    name: str
    size: int
    modified: float


@dataclass
class SpooledUpload:
    """A received body on disk (temporary file), with its digest and size."""

    path: Path
    sha256: str
    size: int

    def read_bytes(self) -> bytes:
        return self.path.read_bytes()

    def discard(self) -> None:
        self.path.unlink(missing_ok=True)


def relative_path(sha256: str) -> str:
    """The blob's path below the store's root (directory or key prefix), from its digest."""
    if len(sha256) != 64 or not set(sha256) <= _HEX:
        raise ValueError("not a sha256 hex digest")
    return f"{sha256[:2]}/{sha256[2:4]}/{sha256}"


def check_relative_path(rel_path: str) -> str:
    """``rel_path`` if it is one :func:`relative_path` gives (what a row stores), else
    ValueError: a damaged row never names another object."""
    if relative_path(rel_path.rsplit("/", 1)[-1]) != rel_path:
        raise ValueError("not a blob path")
    return rel_path


class BlobStore(ABC):
    """What every store shares: the local spool of uploads and the key scheme. Subclasses put
    the spooled bytes in place (:meth:`commit`), read, delete and list them."""

    def __init__(self, tmp_dir: Path):
        self.tmp_dir = tmp_dir

    def ensure_dirs(self) -> None:
        self.tmp_dir.mkdir(parents=True, exist_ok=True)

    def sweep_tmp(self, *, max_age_s: float = TMP_MAX_AGE_S) -> int:
        """Remove temporary files older than ``max_age_s`` (left by a killed process); return
        how many. Younger ones may be another API process's uploads in flight: kept."""
        cutoff = time.time() - max_age_s
        removed = 0
        for path in self.tmp_dir.glob("upload-*"):
            try:
                if path.is_file() and path.stat().st_mtime < cutoff:
                    path.unlink()
                    removed += 1
            except FileNotFoundError:  # its upload finished or another sweep took it
                continue
        return removed

    @staticmethod
    def relative_path(sha256: str) -> str:
        return relative_path(sha256)

    async def spool(self, chunks: AsyncIterator[bytes], *, max_bytes: int) -> SpooledUpload:
        """Write ``chunks`` to a temporary file, hashing as it goes; raise past ``max_bytes``."""
        self.ensure_dirs()
        digest = hashlib.sha256()
        size = 0
        fd, name = tempfile.mkstemp(dir=self.tmp_dir, prefix="upload-")
        try:
            with os.fdopen(fd, "wb") as out:
                async for chunk in chunks:
                    size += len(chunk)
                    if size > max_bytes:
                        raise BlobTooLarge
                    digest.update(chunk)
                    out.write(chunk)
        except BaseException:
            Path(name).unlink(missing_ok=True)
            raise
        return SpooledUpload(Path(name), digest.hexdigest(), size)

    @abstractmethod
    def commit(self, upload: SpooledUpload) -> str:
        """Put a spooled upload in place whole (its temporary file is gone after); return its
        relative blob path. A stored copy with other bytes (damaged) is replaced."""
        raise NotImplementedError

    @abstractmethod
    def read(self, rel_path: str) -> bytes:
        """The blob's bytes; FileNotFoundError when it is not stored."""
        raise NotImplementedError

    @abstractmethod
    def delete(self, rel_path: str) -> None:
        """Remove a stored blob (retention); a missing one is already gone."""
        raise NotImplementedError

    @abstractmethod
    def stored(self) -> Iterator[StoredBlob]:
        """Every object in the store: what GET /storage counts, what the orphan sweep
        (:func:`server.services.retention.sweep_orphans`) looks at."""
        raise NotImplementedError

    @abstractmethod
    def describe(self) -> str:
        """What the store is, as the readiness probe names it."""
        raise NotImplementedError

    @abstractmethod
    def ping(self) -> None:
        """Return when the store can take and give blobs now, quickly (the readiness probe);
        :class:`BlobStoreUnreachable` when it does not answer, OSError when it refuses."""
        raise NotImplementedError


class LocalBlobStore(BlobStore):
    """Blobs as files under ``root`` (``<data_dir>/blobs``), sharded by the digest's first
    two bytes."""

    def __init__(self, root: Path, tmp_dir: Path):
        super().__init__(tmp_dir)
        self.root = root

    def ensure_dirs(self) -> None:
        self.root.mkdir(parents=True, exist_ok=True)
        super().ensure_dirs()

    def path_of(self, sha256: str) -> Path:
        return self.root / relative_path(sha256)

    def commit(self, upload: SpooledUpload) -> str:
        """Move a spooled upload into place atomically (fsync, rename, fsync the directory)."""
        rel = relative_path(upload.sha256)
        final = self.root / rel
        if final.exists() and _sha256_of(final) == upload.sha256:
            os.utime(final)  # written now, as far as the orphan sweep's age test goes
            upload.discard()
            return rel
        # new bytes, or a stored copy damaged on disk: the upload's own copy takes its place
        final.parent.mkdir(parents=True, exist_ok=True)
        with open(upload.path, "rb") as fh:
            os.fsync(fh.fileno())
        os.replace(upload.path, final)
        dir_fd = os.open(final.parent, os.O_RDONLY)
        try:
            os.fsync(dir_fd)
        finally:
            os.close(dir_fd)
        return rel

    def delete(self, rel_path: str) -> None:
        (self.root / check_relative_path(rel_path)).unlink(missing_ok=True)

    def read(self, rel_path: str) -> bytes:
        return (self.root / check_relative_path(rel_path)).read_bytes()

    def stored(self) -> Iterator[StoredBlob]:
        for path, stat in files_under(self.root):
            yield StoredBlob(path.name, stat.st_size, stat.st_mtime)

    def describe(self) -> str:
        return "the data directory's blobs"

    def ping(self) -> None:
        for path in (self.root, self.tmp_dir):
            if not os.access(path, os.W_OK | os.X_OK):
                raise OSError(f"{path.name}: not a writable directory")


def files_under(root: Path) -> Iterator[tuple[Path, os.stat_result]]:
    """Every file under ``root`` with its status, symbolic links not followed (a link counts
    as the link); entries vanishing meanwhile (retention, uploads finishing) are skipped."""
    stack = [root]
    while stack:
        try:
            entries = list(os.scandir(stack.pop()))
        except (FileNotFoundError, NotADirectoryError, PermissionError):
            continue
        for entry in entries:
            try:
                if entry.is_dir(follow_symlinks=False):
                    stack.append(Path(entry.path))
                else:
                    yield Path(entry.path), entry.stat(follow_symlinks=False)
            except FileNotFoundError:
                continue


def _sha256_of(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as fh:
        while chunk := fh.read(1 << 20):
            digest.update(chunk)
    return digest.hexdigest()
