"""Which S3 client the blob store uses: upload + read of N blobs against moto's S3 server.

Run: ``python bench/bench_s3_clients.py [--blobs 50] [--mb 2]`` (from the repository root;
needs ``moto[server]``, ``boto3``, ``obstore``). Each client uploads the same files from disk
(the store uploads from its spooled temporary file), then reads each back whole and checks
its SHA-256; best of three rounds, each to fresh keys. moto's server runs in this process on
a thread, so the figures compare the clients' overheads, not a real store's network.
"""

from __future__ import annotations

import argparse
import hashlib
import logging
import os
import socket
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

os.environ.setdefault("AWS_ACCESS_KEY_ID", "bench")
os.environ.setdefault("AWS_SECRET_ACCESS_KEY", "bench")
os.environ.setdefault("AWS_DEFAULT_REGION", "us-east-1")

BUCKET = "bench"


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _files(tmp: Path, count: int, size: int) -> list[tuple[Path, str]]:
    out = []
    for i in range(count):
        data = os.urandom(size)
        path = tmp / f"blob-{i}"
        path.write_bytes(data)
        out.append((path, hashlib.sha256(data).hexdigest()))
    return out


def boto3_client(endpoint: str) -> tuple[Callable[[str, Path], None], Callable[[str], bytes]]:
    import boto3
    from botocore.config import Config

    s3 = boto3.client("s3", endpoint_url=endpoint,
                      config=Config(s3={"addressing_style": "path"}))

    def put(key: str, path: Path) -> None:
        with open(path, "rb") as fh:
            s3.put_object(Bucket=BUCKET, Key=key, Body=fh)

    def get(key: str) -> bytes:
        return s3.get_object(Bucket=BUCKET, Key=key)["Body"].read()

    return put, get


def pyarrow_client(endpoint: str) -> tuple[Callable[[str, Path], None], Callable[[str], bytes]]:
    from pyarrow import fs

    s3 = fs.S3FileSystem(endpoint_override=endpoint, scheme="http", region="us-east-1",
                         access_key="bench", secret_key="bench")

    def put(key: str, path: Path) -> None:
        with open(path, "rb") as src, s3.open_output_stream(f"{BUCKET}/{key}") as out:
            while chunk := src.read(1 << 20):
                out.write(chunk)

    def get(key: str) -> bytes:
        with s3.open_input_stream(f"{BUCKET}/{key}") as src:
            return bytes(src.readall())

    return put, get


def obstore_client(endpoint: str) -> tuple[Callable[[str, Path], None], Callable[[str], bytes]]:
    import obstore
    from obstore.store import S3Store

    s3 = S3Store(BUCKET, endpoint=endpoint, region="us-east-1", access_key_id="bench",
                 secret_access_key="bench", client_options={"allow_http": True})

    def put(key: str, path: Path) -> None:
        obstore.put(s3, key, path)

    def get(key: str) -> bytes:
        return bytes(obstore.get(s3, key).bytes())

    return put, get


CLIENTS = {"boto3": boto3_client, "pyarrow.fs.S3FileSystem": pyarrow_client,
           "obstore": obstore_client}


def _round(put: Callable[[str, Path], None], get: Callable[[str], bytes],
           files: list[tuple[Path, str]], tag: str) -> tuple[float, float]:
    t0 = time.perf_counter()
    for i, (path, _) in enumerate(files):
        put(f"{tag}/{i}", path)
    t1 = time.perf_counter()
    for i, (_, sha) in enumerate(files):
        if hashlib.sha256(get(f"{tag}/{i}")).hexdigest() != sha:
            raise AssertionError(f"{tag}/{i} read back different bytes")
    return t1 - t0, time.perf_counter() - t1


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--blobs", type=int, default=50)
    parser.add_argument("--mb", type=float, default=2.0)
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    import boto3
    from moto.server import ThreadedMotoServer

    logging.getLogger("werkzeug").setLevel(logging.ERROR)  # one line per request otherwise
    port = _free_port()
    server = ThreadedMotoServer(ip_address="127.0.0.1", port=port, verbose=False)
    server.start()
    endpoint = f"http://127.0.0.1:{port}"
    try:
        boto3.client("s3", endpoint_url=endpoint).create_bucket(Bucket=BUCKET)
        with tempfile.TemporaryDirectory() as tmp:
            files = _files(Path(tmp), args.blobs, int(args.mb * 1024 * 1024))
            total_mb = args.blobs * args.mb
            print(f"{args.blobs} blobs x {args.mb:g} MB, best of {args.rounds} rounds")
            print("| client | upload [s] | read [s] | upload [MB/s] | read [MB/s] |")
            print("|---|---|---|---|---|")
            for name, make in CLIENTS.items():
                put, get = make(endpoint)
                runs = [_round(put, get, files, f"{name}-{r}") for r in range(args.rounds)]
                up, down = min(r[0] for r in runs), min(r[1] for r in runs)
                print(f"| {name} | {up:.2f} | {down:.2f} | {total_mb / up:.0f} | "
                      f"{total_mb / down:.0f} |")
    finally:
        server.stop()


if __name__ == "__main__":
    main()
