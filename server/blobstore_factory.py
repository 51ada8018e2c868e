"""The one place a blob store is built from settings: the only module that knows both stores.

:mod:`server.blobstore` holds the contract and the local store, :mod:`server.blobstore_s3` the
object store built on that contract; choosing between them lives here, above both, so neither
store module imports the other's side (the layers contract in ``pyproject.toml`` keeps it so).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from server.blobstore import BlobStore, LocalBlobStore

if TYPE_CHECKING:
    from server.config import Settings

__all__ = ["open_blob_store"]


def open_blob_store(settings: Settings) -> BlobStore:
    """The store the settings name: the object store of ``HMSM_BLOB_URL`` when set, else the
    data directory's ``blobs``. Its directories exist on return; nothing is contacted."""
    store: BlobStore
    if settings.blob_url is not None:
        from server.blobstore_s3 import S3BlobStore  # boto3 loads only when it is used

        store = S3BlobStore.from_settings(settings)
    else:
        store = LocalBlobStore(settings.blob_dir, settings.tmp_dir)
    store.ensure_dirs()
    return store
