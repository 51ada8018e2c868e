"""Content-addressed storage of raw flight files under ``<data_dir>/blobs``.

A blob is streamed to a temporary file in ``<data_dir>/tmp`` (same filesystem), fsynced, then
renamed into place, so a reader never sees a half-written blob and a crash leaves only a
temporary file. The path is derived from the SHA-256 alone: no client string reaches the path.
"""

from __future__ import annotations

import hashlib
import os
import tempfile
from collections.abc import AsyncIterator
from dataclasses import dataclass
from pathlib import Path

__all__ = ["BlobStore", "SpooledUpload", "BlobTooLarge"]

_HEX = set("0123456789abcdef")


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
        if final.exists():
            upload.discard()
            return rel
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

    def read(self, rel_path: str) -> bytes:
        path = (self.root / rel_path).resolve()
        if self.root.resolve() not in path.parents:
            raise ValueError("blob path outside the store")
        return path.read_bytes()
