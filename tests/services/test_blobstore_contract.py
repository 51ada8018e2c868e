"""The blob store's contract, the same for the local directory and an S3 server over HTTP
(moto's): what commit, read, delete, stored and the start-up sweep promise their callers."""

from __future__ import annotations

import asyncio
import hashlib
import os
import time
from collections.abc import AsyncIterator
from pathlib import Path

import pytest

from server.blobstore import BlobStore, BlobTooLarge, LocalBlobStore, SpooledUpload
from server.config import Settings

BACKENDS = ["local", "s3"]


@pytest.fixture(params=BACKENDS)
def store(request: pytest.FixtureRequest, tmp_path: Path) -> BlobStore:
    if request.param == "local":
        blobs: BlobStore = LocalBlobStore(tmp_path / "blobs", tmp_path / "tmp")
    else:
        from server.blobstore_factory import open_blob_store

        s3 = request.getfixturevalue("s3_server")
        blobs = open_blob_store(Settings(data_dir=tmp_path, blob_url=f"s3://{s3.new_bucket()}/logs",
                                         s3_endpoint_url=s3.endpoint))
    blobs.ensure_dirs()
    return blobs


async def _chunks(data: bytes, size: int = 1 << 16) -> AsyncIterator[bytes]:
    for i in range(0, len(data), size):
        yield data[i:i + size]


def spool(blobs: BlobStore, data: bytes, max_bytes: int = 64 << 20) -> SpooledUpload:
    return asyncio.run(blobs.spool(_chunks(data), max_bytes=max_bytes))


def damage(blobs: BlobStore, rel: str) -> None:
    """Other bytes under the blob's name: a disk fault locally, a stray writer in the bucket."""
    if isinstance(blobs, LocalBlobStore):
        (blobs.root / rel).write_bytes(b"damaged")
    else:
        blobs.client.put_object(Bucket=blobs.bucket, Key=blobs.prefix + rel, Body=b"damaged")


def test_commit_puts_the_bytes_under_their_digest_and_read_returns_them(store) -> None:  # type: ignore[no-untyped-def]
    data = os.urandom(300_000)
    upload = spool(store, data)
    sha = hashlib.sha256(data).hexdigest()
    assert (upload.sha256, upload.size) == (sha, len(data))
    rel = store.commit(upload)
    assert rel == f"{sha[:2]}/{sha[2:4]}/{sha}"
    assert store.read(rel) == data
    assert not upload.path.exists()  # the spooled file is gone once committed
    assert [(b.name, b.size) for b in store.stored()] == [(sha, len(data))]


def test_the_same_bytes_twice_are_one_blob(store) -> None:  # type: ignore[no-untyped-def]
    data = b"flight log" * 1000
    first = store.commit(spool(store, data))
    second = spool(store, data)
    assert store.commit(second) == first
    assert not second.path.exists()
    assert [b.size for b in store.stored()] == [len(data)]


def test_committing_stored_bytes_again_renews_their_date(store) -> None:  # type: ignore[no-untyped-def]
    """What keeps the orphan sweep off a blob a new row is about to refer to."""
    data = b"pruned once, sent again"
    store.commit(spool(store, data))
    first = next(iter(store.stored())).modified
    time.sleep(1.1)  # S3 dates to the second
    store.commit(spool(store, data))
    assert next(iter(store.stored())).modified >= first + 1


def test_a_damaged_stored_copy_is_replaced_by_the_upload(store) -> None:  # type: ignore[no-untyped-def]
    data = os.urandom(50_000)
    rel = store.commit(spool(store, data))
    damage(store, rel)
    assert store.read(rel) != data
    assert store.commit(spool(store, data)) == rel
    assert store.read(rel) == data


def test_a_blob_larger_than_a_part_round_trips(store) -> None:  # type: ignore[no-untyped-def]
    from server.blobstore_s3 import PART_BYTES

    data = os.urandom(PART_BYTES * 2 + 12345)  # three parts in the object store
    rel = store.commit(spool(store, data))
    assert hashlib.sha256(store.read(rel)).digest() == hashlib.sha256(data).digest()
    assert [(b.name, b.size) for b in store.stored()] == [(rel.rsplit("/", 1)[-1], len(data))]


def test_delete_removes_and_a_missing_blob_is_already_gone(store) -> None:  # type: ignore[no-untyped-def]
    keep = store.commit(spool(store, b"kept"))
    gone = store.commit(spool(store, b"removed"))
    store.delete(gone)
    store.delete(gone)  # twice: no error
    with pytest.raises(FileNotFoundError):
        store.read(gone)
    assert store.read(keep) == b"kept"
    assert [b.name for b in store.stored()] == [keep.rsplit("/", 1)[-1]]


@pytest.mark.parametrize("bad", ["../../etc/passwd", "ab/cd/" + "0" * 64, "x" * 70])
def test_a_path_no_digest_gives_is_refused(store, bad: str) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(ValueError):
        store.read(bad)
    with pytest.raises(ValueError):
        store.delete(bad)


def test_spool_past_the_limit_keeps_nothing(store) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(BlobTooLarge):
        spool(store, b"x" * 1000, max_bytes=999)
    assert list(store.tmp_dir.iterdir()) == []
    assert list(store.stored()) == []


def test_sweep_tmp_removes_old_temporary_files_only(store) -> None:  # type: ignore[no-untyped-def]
    old, young = spool(store, b"old"), spool(store, b"young")
    past = time.time() - 3600
    os.utime(old.path, (past, past))
    assert store.sweep_tmp(max_age_s=600) == 1
    assert not old.path.exists() and young.path.exists()


def _multipart_uploads(blobs) -> list[str]:  # type: ignore[no-untyped-def]
    listing = blobs.client.list_multipart_uploads(Bucket=blobs.bucket)
    return [u["Key"] for u in listing.get("Uploads", [])]


def test_sweep_aborts_the_multipart_upload_of_a_killed_process(tmp_path, s3_server) -> None:  # type: ignore[no-untyped-def]
    from server.blobstore_factory import open_blob_store

    bucket = s3_server.new_bucket()
    blobs = open_blob_store(Settings(data_dir=tmp_path, blob_url=f"s3://{bucket}/logs",
                                     s3_endpoint_url=s3_server.endpoint))
    # what a process killed between two parts leaves: an upload started, one part sent
    started = blobs.client.create_multipart_upload(Bucket=bucket, Key="logs/aa/bb/orphan")
    blobs.client.upload_part(Bucket=bucket, Key="logs/aa/bb/orphan", PartNumber=1,
                             UploadId=started["UploadId"], Body=b"x" * 1024)
    assert _multipart_uploads(blobs) == ["logs/aa/bb/orphan"]
    # (moto dates every multipart upload 2010-11-10, so "a young one is kept" is not
    # observable here: the age test is the same comparison as the local files')
    assert blobs.sweep_tmp(max_age_s=600) == 1
    assert _multipart_uploads(blobs) == []
    assert s3_server.keys(bucket) == []


def test_a_store_down_is_unreachable_not_missing(tmp_path) -> None:  # type: ignore[no-untyped-def]
    """Nothing listening: BlobStoreUnreachable (the API's 503) after the retries, quickly."""
    from server.blobstore import BlobStoreUnreachable
    from server.blobstore_factory import open_blob_store
    from tests.s3_server import AWS_ENV, MotoS3

    with pytest.MonkeyPatch.context() as mp:
        for name, value in AWS_ENV.items():
            mp.setenv(name, value)
        down = MotoS3()  # a free port, never started
        blobs = open_blob_store(Settings(data_dir=tmp_path, blob_url="s3://hmsm-down",
                                         s3_endpoint_url=down.endpoint))
        upload = spool(blobs, b"bytes")
        start = time.monotonic()
        for call in (lambda: blobs.commit(upload), lambda: blobs.read(blobs.relative_path(
                upload.sha256))):
            with pytest.raises(BlobStoreUnreachable):
                call()
        assert time.monotonic() - start < 30
        assert upload.path.exists()  # a failed commit leaves the upload to its owner


def test_store_init_creates_the_bucket_once(tmp_path, s3_server, monkeypatch, capsys) -> None:  # type: ignore[no-untyped-def]
    from server.cli import main

    bucket = f"hmsm-init-{os.urandom(4).hex()}"
    monkeypatch.setenv("HMSM_DATA_DIR", str(tmp_path))
    monkeypatch.setenv("HMSM_BLOB_URL", f"s3://{bucket}/flights")
    monkeypatch.setenv("HMSM_S3_ENDPOINT_URL", s3_server.endpoint)
    assert main(["store", "init"]) == 0
    assert "bucket created" in capsys.readouterr().out
    assert s3_server.keys(bucket) == []  # it exists (a missing bucket would raise)
    assert main(["store", "init"]) == 0
    assert "bucket exists" in capsys.readouterr().out
