"""Content-addressed storage of raw flight files under ``<data_dir>/blobs``.

A blob is streamed to a temporary file in ``<data_dir>/tmp`` (same filesystem), fsynced, then
renamed into place, so a reader never sees a half-written blob and a crash leaves only a
temporary file, which :meth:`BlobStore.sweep_tmp` removes at the next start. The path is
derived from the SHA-256 alone: no client string reaches the path.
"""

from __future__ import annotations

import hashlib
import os
import tempfile
import time
from collections.abc import AsyncIterator
from dataclasses import dataclass
from pathlib import Path

__all__ = ["BlobStore", "SpooledUpload", "BlobTooLarge"]

_HEX = set("0123456789abcdef")
#: temporary files older than this at start-up belong to no live upload (one spools in seconds)
TMP_MAX_AGE_S = 10 * 60


class BlobTooLarge(Exception):
    """The stream went past the size limit; nothing was kept."""


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


class BlobStore:
    def __init__(self, root: Path, tmp_dir: Path):
        self.root = root
        self.tmp_dir = tmp_dir

    def ensure_dirs(self) -> None:
        self.root.mkdir(parents=True, exist_ok=True)
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

    def relative_path(self, sha256: str) -> str:
        if len(sha256) != 64 or not set(sha256) <= _HEX:
            raise ValueError("not a sha256 hex digest")
        return f"{sha256[:2]}/{sha256[2:4]}/{sha256}"

    def path_of(self, sha256: str) -> Path:
        return self.root / self.relative_path(sha256)

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

    def commit(self, upload: SpooledUpload) -> str:
        """Move a spooled upload into place atomically; return its relative blob path."""
        rel = self.relative_path(upload.sha256)
        final = self.root / rel
        if final.exists() and _sha256_of(final) == upload.sha256:
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
        """Remove a stored blob (retention); a missing one is already gone."""
        path = (self.root / rel_path).resolve()
        if self.root.resolve() not in path.parents:
            raise ValueError("blob path outside the store")
        path.unlink(missing_ok=True)

    def read(self, rel_path: str) -> bytes:
        path = (self.root / rel_path).resolve()
        if self.root.resolve() not in path.parents:
            raise ValueError("blob path outside the store")
        return path.read_bytes()


def _sha256_of(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as fh:
        while chunk := fh.read(1 << 20):
            digest.update(chunk)
    return digest.hexdigest()
