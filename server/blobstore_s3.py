"""Flight logs in an S3-compatible object store (``HMSM_BLOB_URL=s3://bucket/prefix``).

The object key is ``<prefix>/<aa>/<bb>/<sha256>``: the same relative path a row stores for a
local blob, so rows do not say where the bytes live. A blob goes up from the spooled temporary
file, never whole in memory: one PUT up to :data:`PART_BYTES`, a multipart upload of such parts
past it (aborted when a part fails). S3 makes an object visible only once its PUT or multipart
upload completes, so a reader sees the whole blob or none. The object carries its SHA-256 as
user metadata, how :meth:`S3BlobStore.commit` tells a stored copy from a damaged one without
reading it back.

boto3 is the client (docs/BENCHMARKS.md, "Object-store clients"): its standard retry mode retries
connection errors, throttling and 5xx answers with exponential backoff and jitter; what still
fails after :data:`ATTEMPTS` is :class:`~server.blobstore.BlobStoreUnreachable` (the API's 503).
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterator
from datetime import UTC, datetime, timedelta
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

import boto3
from botocore.config import Config
from botocore.exceptions import BotoCoreError, ClientError
from botocore.exceptions import ConnectionError as BotoConnectionError

from server.blobstore import (
    TMP_MAX_AGE_S,
    BlobStore,
    BlobStoreUnreachable,
    SpooledUpload,
    StoredBlob,
    check_relative_path,
    relative_path,
)

if TYPE_CHECKING:
    from server.config import Settings

__all__ = ["S3BlobStore", "PART_BYTES", "ATTEMPTS"]

log = logging.getLogger("hmsm.blobstore")

#: one PUT up to this size, multipart parts of it past it: what an upload holds in memory
#: (S3's smallest part is 5 MiB; a 64 MiB upload limit makes at most 8 parts)
PART_BYTES = 8 * 1024 * 1024
#: tries of one request (the first included), botocore's standard backoff between them
ATTEMPTS = 4
#: user metadata holding the object's SHA-256 (S3 sends it as x-amz-meta-sha256)
SHA_META = "sha256"
_NOT_FOUND = {"404", "NoSuchKey", "NotFound"}

T = TypeVar("T")


class S3BlobStore(BlobStore):
    def __init__(self, client: Any, bucket: str, prefix: str, tmp_dir: Path):
        super().__init__(tmp_dir)
        self.client = client
        self.bucket = bucket
        self.prefix = f"{prefix}/" if prefix else ""

    @classmethod
    def from_settings(cls, settings: Settings) -> S3BlobStore:
        bucket, prefix = settings.blob_bucket
        return cls(make_client(settings.s3_endpoint_url), bucket, prefix, settings.tmp_dir)

    def ensure_bucket(self) -> bool:
        """Create the bucket unless it exists (``hmsm store init``); True when created."""
        try:
            _call(lambda: self.client.head_bucket(Bucket=self.bucket))
            return False
        except FileNotFoundError:
            pass
        region = self.client.meta.region_name
        where = ({} if region in (None, "us-east-1") else
                 {"CreateBucketConfiguration": {"LocationConstraint": region}})
        _call(lambda: self.client.create_bucket(Bucket=self.bucket, **where))
        return True

    def _key(self, rel_path: str) -> str:
        return self.prefix + check_relative_path(rel_path)

    def commit(self, upload: SpooledUpload) -> str:
        rel = relative_path(upload.sha256)
        key = self.prefix + rel
        meta = {SHA_META: upload.sha256}
        if self._stored_sha(key) == upload.sha256:
            self._renew(key, meta)
        elif upload.size <= PART_BYTES:  # new bytes, or a damaged copy: replaced
            with open(upload.path, "rb") as body:
                _call(lambda: self.client.put_object(Bucket=self.bucket, Key=key, Body=body,
                                                     Metadata=meta))
        else:
            self._multipart(upload.path, key, meta)
        upload.discard()
        return rel

    def _stored_sha(self, key: str) -> str | None:
        try:
            head = _call(lambda: self.client.head_object(Bucket=self.bucket, Key=key))
        except FileNotFoundError:
            return None
        return str(head.get("Metadata", {}).get(SHA_META, "")) or None

    def _renew(self, key: str, meta: dict[str, str]) -> None:
        """The stored object's date brought to now (a copy onto itself, inside the store): it
        backs a new row, so the orphan sweep must not take it for an old orphan."""
        _call(lambda: self.client.copy_object(
            Bucket=self.bucket, Key=key, CopySource={"Bucket": self.bucket, "Key": key},
            Metadata=meta, MetadataDirective="REPLACE"))

    def _multipart(self, path: Path, key: str, meta: dict[str, str]) -> None:
        """Upload ``path`` in parts of :data:`PART_BYTES`; on any failure abort the upload
        (its parts are otherwise kept, and billed, invisibly) and raise."""
        upload_id = _call(lambda: self.client.create_multipart_upload(
            Bucket=self.bucket, Key=key, Metadata=meta))["UploadId"]
        try:
            parts: list[dict[str, Any]] = []
            with open(path, "rb") as fh:
                while chunk := fh.read(PART_BYTES):
                    part = {"Bucket": self.bucket, "Key": key, "UploadId": upload_id,
                            "PartNumber": len(parts) + 1, "Body": chunk}
                    etag = _call(partial(self.client.upload_part, **part))["ETag"]
                    parts.append({"ETag": etag, "PartNumber": part["PartNumber"]})
            _call(lambda: self.client.complete_multipart_upload(
                Bucket=self.bucket, Key=key, UploadId=upload_id,
                MultipartUpload={"Parts": parts}))
        except BaseException:
            self._abort(key, upload_id)
            raise

    def _abort(self, key: str, upload_id: str) -> None:
        try:
            self.client.abort_multipart_upload(Bucket=self.bucket, Key=key, UploadId=upload_id)
        except (BotoCoreError, ClientError) as exc:  # the start-up sweep takes it later
            log.warning("could not abort multipart upload of %s: %s", key, exc)

    def read(self, rel_path: str) -> bytes:
        key = self._key(rel_path)
        return _call(lambda: self.client.get_object(Bucket=self.bucket, Key=key)["Body"].read())

    def delete(self, rel_path: str) -> None:
        key = self._key(rel_path)  # S3 answers a missing key with success too
        _call(lambda: self.client.delete_object(Bucket=self.bucket, Key=key))

    def stored(self) -> Iterator[StoredBlob]:
        pages = iter(self.client.get_paginator("list_objects_v2").paginate(
            Bucket=self.bucket, Prefix=self.prefix))
        while (page := _call(lambda: next(pages, None))) is not None:  # a page at a time
            for item in page.get("Contents", []):
                yield StoredBlob(item["Key"].rsplit("/", 1)[-1], int(item["Size"]),
                                 item["LastModified"].timestamp())

    def sweep_tmp(self, *, max_age_s: float = TMP_MAX_AGE_S) -> int:
        """The local spool's old temporary files, and the multipart uploads under the prefix
        started more than ``max_age_s`` ago (a process killed mid-upload): both belong to no
        live upload. A store not answering now is left for the next start."""
        removed = super().sweep_tmp(max_age_s=max_age_s)
        try:
            return removed + self._abort_stale_uploads(max_age_s)
        except OSError as exc:
            log.warning("could not sweep unfinished multipart uploads: %s", exc)
            return removed

    def _abort_stale_uploads(self, max_age_s: float) -> int:
        cutoff = datetime.now(UTC) - timedelta(seconds=max_age_s)
        pages = self.client.get_paginator("list_multipart_uploads").paginate(
            Bucket=self.bucket, Prefix=self.prefix)
        stale = [(u["Key"], u["UploadId"]) for page in _call(lambda: list(pages))
                 for u in page.get("Uploads", []) if u["Initiated"] < cutoff]
        for key, upload_id in stale:
            self._abort(key, upload_id)
        return len(stale)


def make_client(endpoint_url: str | None) -> Any:
    """A boto3 S3 client: credentials and region from the standard AWS_* variables (or the
    instance's role); path-style addressing on a server of our own (no wildcard DNS needed)."""
    own_server = endpoint_url is not None
    # On a server of our own, checksums only where S3 requires them: botocore's default
    # trailing CRC32 (aws-chunked uploads, boto3 >= 1.36) is not supported by some
    # S3-compatible servers; the worker checks the bytes' SHA-256 before analysis either way.
    checksums = "when_required" if own_server else "when_supported"
    config = Config(retries={"max_attempts": ATTEMPTS, "mode": "standard"},
                    connect_timeout=3, read_timeout=30,
                    request_checksum_calculation=checksums,
                    response_checksum_validation=checksums,
                    s3={"addressing_style": "path" if own_server else "auto"})
    return boto3.session.Session().client("s3", endpoint_url=endpoint_url, config=config)


def _call(request: Callable[[], T]) -> T:
    """``request()`` with botocore's failures as the OSErrors the callers handle: a missing
    key FileNotFoundError, no answer (retries spent) :class:`BlobStoreUnreachable`, a refusal
    (credentials, no such bucket) a plain OSError."""
    try:
        return request()
    except ClientError as exc:
        error = exc.response.get("Error", {})
        code = str(error.get("Code", ""))
        status = int(exc.response.get("ResponseMetadata", {}).get("HTTPStatusCode") or 0)
        if code in _NOT_FOUND:
            raise FileNotFoundError(f"no such blob: {code}") from None
        if status >= 500 or code in ("SlowDown", "RequestTimeout"):
            raise BlobStoreUnreachable(f"object store answered {status} {code}") from exc
        raise OSError(f"object store refused: {status} {code} {error.get('Message', '')}"
                      ) from exc
    except BotoConnectionError as exc:
        raise BlobStoreUnreachable(f"object store unreachable: {exc}") from exc
    except BotoCoreError as exc:  # read timeouts, closed connections, broken responses
        raise BlobStoreUnreachable(f"object store failed: {exc}") from exc
