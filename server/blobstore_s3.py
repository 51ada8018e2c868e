"""Flight logs in an S3-compatible object store (``HMSM_BLOB_URL=s3://bucket/prefix``).

The object key is ``<prefix>/<aa>/<bb>/<sha256>``: the same relative path a row stores for a
local blob, so rows do not say where the bytes live. A blob goes up from the spooled temporary
file, never whole in memory: one PUT up to :data:`PART_BYTES`, a multipart upload of such parts
past it (aborted when a part fails). S3 makes an object visible only once its PUT or multipart
upload completes, so a reader sees the whole blob or none. The object carries its SHA-256 as
user metadata, how :meth:`S3BlobStore.commit` tells a stored copy from a damaged one without
reading it back.

boto3 is the client (docs/BENCHMARKS.md, "Object-store clients"): its standard retry mode retries
connection errors, throttling and 5xx answers with exponential backoff and jitter, up to
:data:`ATTEMPTS` tries; what still fails is :class:`~server.blobstore.BlobStoreUnreachable` (the
API's 503).

Every operation (an upload's commit: its HEAD, then the PUT, copy or parts; a read; a delete;
one listing page) has a deadline, ``HMSM_BLOB_STORE_DEADLINE_S``: no try, first or retry, starts
unless it can end within it (its connect and read timeouts, and the longest backoff before it).
A store that accepts connections and never answers is so given up within the deadline, rather
than after botocore's tries at their full read timeout (4 x 30 s with backoff: about 150 s,
longer than a client waits, holding one of the server's connection slots all along).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass
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

__all__ = ["S3BlobStore", "StoreTimeouts", "PART_BYTES", "ATTEMPTS"]

log = logging.getLogger("hmsm.blobstore")

#: one PUT up to this size, multipart parts of it past it: what an upload holds in memory
#: (S3's smallest part is 5 MiB; a 64 MiB upload limit makes at most 8 parts)
PART_BYTES = 8 * 1024 * 1024
#: tries of one request at most (the first included), botocore's standard backoff between them;
#: fewer when the operation's deadline has no room for another
ATTEMPTS = 4
#: botocore's standard backoff before try n+1 is at most min(2**(n-1), 20) s (for throttling;
#: 20 times less otherwise), plus up to 5 s when the store sends x-amz-retry-after
#: (botocore.retries.standard.ExponentialBackoff)
_BACKOFF_CAP_S = 20.0
_RETRY_AFTER_EXTRA_S = 5.0
#: user metadata holding the object's SHA-256 (S3 sends it as x-amz-meta-sha256)
SHA_META = "sha256"
_NOT_FOUND = {"404", "NoSuchKey", "NotFound"}

T = TypeVar("T")

#: the monotonic time by which the store operation running here must end (None: none runs).
#: A context variable: one client serves every thread of the API's pool
_DEADLINE: ContextVar[float | None] = ContextVar("hmsm_blob_store_deadline", default=None)


@dataclass(frozen=True)
class StoreTimeouts:
    """How long the store is waited for [s]; the defaults and their reasons are
    :class:`server.config.Settings`' ``blob_store_*`` fields."""

    connect_s: float
    read_s: float
    deadline_s: float
    probe_s: float

    @classmethod
    def from_settings(cls, settings: Settings) -> StoreTimeouts:
        return cls(settings.blob_store_connect_timeout_s, settings.blob_store_read_timeout_s,
                   settings.blob_store_deadline_s, settings.blob_store_probe_timeout_s)

    @property
    def try_s(self) -> float:
        """The longest one try of a request waits on a store that does not answer."""
        return self.connect_s + self.read_s


class S3BlobStore(BlobStore):
    def __init__(self, client: Any, bucket: str, prefix: str, tmp_dir: Path,
                 timeouts: StoreTimeouts, probe_client: Any = None):
        super().__init__(tmp_dir)
        self.client = client
        self.probe_client = probe_client
        self.bucket = bucket
        self.prefix = f"{prefix}/" if prefix else ""
        self.timeouts = timeouts
        # first of the needs-retry handlers: botocore takes the first answer that is not None
        # (botocore.endpoint.Endpoint._needs_retry), so this one's False stops a retry
        client.meta.events.register_first("needs-retry.s3", self._retry_within_deadline)

    @classmethod
    def from_settings(cls, settings: Settings) -> S3BlobStore:
        bucket, prefix = settings.blob_bucket
        timeouts = StoreTimeouts.from_settings(settings)
        return cls(make_client(settings.s3_endpoint_url, timeouts), bucket, prefix,
                   settings.tmp_dir, timeouts,
                   make_client(settings.s3_endpoint_url, timeouts, probe=True))

    def describe(self) -> str:
        return f"s3://{self.bucket}/{self.prefix}".rstrip("/")

    def ping(self) -> None:
        """One HEAD of the bucket, not retried, its connect and its answer each within the
        probe timeout: what the readiness probe asks."""
        try:
            _call(lambda: (self.probe_client or self.client).head_bucket(Bucket=self.bucket))
        except FileNotFoundError:
            raise OSError(f"object store: no bucket {self.bucket} (`hmsm store init` creates "
                          "it)") from None

    @contextmanager
    def _operation(self) -> Iterator[None]:
        """One deadline for the requests made inside; a nested operation keeps the outer's."""
        if _DEADLINE.get() is not None:
            yield
            return
        token = _DEADLINE.set(time.monotonic() + self.timeouts.deadline_s)
        try:
            yield
        finally:
            _DEADLINE.reset(token)

    def _call(self, request: Callable[[], T]) -> T:
        """:func:`_call` within the running operation's deadline (or one of its own): a
        request whose first try could not end before it is not started."""
        with self._operation():
            deadline = _DEADLINE.get()
            if deadline is not None and time.monotonic() + self.timeouts.try_s > deadline:
                raise BlobStoreUnreachable(
                    "object store: no time left for another request within the "
                    f"{self.timeouts.deadline_s:g} s deadline")
            return _call(request)

    def _retry_within_deadline(self, attempts: int, response: Any = None,
                               **_: Any) -> bool | None:
        """botocore's needs-retry hook: False (no retry) when the longest backoff and one more
        try would pass the operation's deadline; otherwise None, leaving the choice to the
        retry mode (which retries only a failure)."""
        deadline = _DEADLINE.get()
        if deadline is None:
            return None
        backoff = min(2.0 ** (attempts - 1), _BACKOFF_CAP_S)
        http = response[0] if response else None
        if http is not None and "x-amz-retry-after" in http.headers:
            backoff += _RETRY_AFTER_EXTRA_S
        if time.monotonic() + backoff + self.timeouts.try_s > deadline:
            return False
        return None

    def ensure_bucket(self) -> bool:
        """Create the bucket unless it exists (``hmsm store init``); True when created."""
        try:
            self._call(lambda: self.client.head_bucket(Bucket=self.bucket))
            return False
        except FileNotFoundError:
            pass
        region = self.client.meta.region_name
        where = ({} if region in (None, "us-east-1") else
                 {"CreateBucketConfiguration": {"LocationConstraint": region}})
        self._call(lambda: self.client.create_bucket(Bucket=self.bucket, **where))
        return True

    def _key(self, rel_path: str) -> str:
        return self.prefix + check_relative_path(rel_path)

    def commit(self, upload: SpooledUpload) -> str:
        rel = relative_path(upload.sha256)
        key = self.prefix + rel
        meta = {SHA_META: upload.sha256}
        with self._operation():  # the HEAD, then the PUT, copy or parts: one deadline
            if self._stored_sha(key) == upload.sha256:
                self._renew(key, meta)
            elif upload.size <= PART_BYTES:  # new bytes, or a damaged copy: replaced
                with open(upload.path, "rb") as body:
                    self._call(lambda: self.client.put_object(
                        Bucket=self.bucket, Key=key, Body=body, Metadata=meta))
            else:
                self._multipart(upload.path, key, meta)
        upload.discard()
        return rel

    def _stored_sha(self, key: str) -> str | None:
        try:
            head = self._call(lambda: self.client.head_object(Bucket=self.bucket, Key=key))
        except FileNotFoundError:
            return None
        return str(head.get("Metadata", {}).get(SHA_META, "")) or None

    def _renew(self, key: str, meta: dict[str, str]) -> None:
        """The stored object's date brought to now (a copy onto itself, inside the store): it
        backs a new row, so the orphan sweep must not take it for an old orphan."""
        self._call(lambda: self.client.copy_object(
            Bucket=self.bucket, Key=key, CopySource={"Bucket": self.bucket, "Key": key},
            Metadata=meta, MetadataDirective="REPLACE"))

    def _multipart(self, path: Path, key: str, meta: dict[str, str]) -> None:
        """Upload ``path`` in parts of :data:`PART_BYTES`; on any failure abort the upload
        (its parts are otherwise kept, and billed, invisibly) and raise."""
        upload_id = self._call(lambda: self.client.create_multipart_upload(
            Bucket=self.bucket, Key=key, Metadata=meta))["UploadId"]
        try:
            parts: list[dict[str, Any]] = []
            with open(path, "rb") as fh:
                while chunk := fh.read(PART_BYTES):
                    part = {"Bucket": self.bucket, "Key": key, "UploadId": upload_id,
                            "PartNumber": len(parts) + 1, "Body": chunk}
                    etag = self._call(partial(self.client.upload_part, **part))["ETag"]
                    parts.append({"ETag": etag, "PartNumber": part["PartNumber"]})
            self._call(lambda: self.client.complete_multipart_upload(
                Bucket=self.bucket, Key=key, UploadId=upload_id,
                MultipartUpload={"Parts": parts}))
        except BaseException:
            self._abort(key, upload_id)
            raise

    def _abort(self, key: str, upload_id: str) -> None:
        try:
            self._call(lambda: self.client.abort_multipart_upload(
                Bucket=self.bucket, Key=key, UploadId=upload_id))
        except OSError as exc:  # the store away, or no time left: the start-up sweep takes it
            log.warning("could not abort multipart upload of %s: %s", key, exc)

    def read(self, rel_path: str) -> bytes:
        key = self._key(rel_path)
        return self._call(
            lambda: self.client.get_object(Bucket=self.bucket, Key=key)["Body"].read())

    def delete(self, rel_path: str) -> None:
        key = self._key(rel_path)  # S3 answers a missing key with success too
        self._call(lambda: self.client.delete_object(Bucket=self.bucket, Key=key))

    def stored(self) -> Iterator[StoredBlob]:
        pages = iter(self.client.get_paginator("list_objects_v2").paginate(
            Bucket=self.bucket, Prefix=self.prefix))
        while (page := self._call(lambda: next(pages, None))) is not None:  # a page at a time
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
        stale = [(u["Key"], u["UploadId"]) for page in self._call(lambda: list(pages))
                 for u in page.get("Uploads", []) if u["Initiated"] < cutoff]
        for key, upload_id in stale:
            self._abort(key, upload_id)
        return len(stale)


def make_client(endpoint_url: str | None, timeouts: StoreTimeouts, *,
                probe: bool = False) -> Any:
    """A boto3 S3 client: credentials and region from the standard AWS_* variables (or the
    instance's role); path-style addressing on a server of our own (no wildcard DNS needed).
    The readiness probe's (``probe``) tries once, its connect and answer each within the probe
    timeout."""
    own_server = endpoint_url is not None
    # On a server of our own, checksums only where S3 requires them: botocore's default
    # trailing CRC32 (aws-chunked uploads, boto3 >= 1.36) is not supported by some
    # S3-compatible servers; the worker checks the bytes' SHA-256 before analysis either way.
    checksums = "when_required" if own_server else "when_supported"
    if probe:
        waits: dict[str, Any] = {"retries": {"total_max_attempts": 1, "mode": "standard"},
                                 "connect_timeout": timeouts.probe_s,
                                 "read_timeout": timeouts.probe_s}
    else:
        waits = {"retries": {"total_max_attempts": ATTEMPTS, "mode": "standard"},
                 "connect_timeout": timeouts.connect_s, "read_timeout": timeouts.read_s}
    config = Config(**waits, request_checksum_calculation=checksums,
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
