"""moto's S3 server over HTTP on a free local port, for the object-store tests: the real
client, the real wire protocol, a server the test may stop and start again (an outage).

moto keeps its buckets in this process, so a server started again serves what it held; each
test takes a bucket of its own. :class:`SilentServer` is the other outage: a store that takes
connections and never answers.
"""

from __future__ import annotations

import logging
import socket
import threading
import uuid

import boto3

__all__ = ["MotoS3", "SilentServer", "AWS_ENV"]

#: what boto3 reads from the environment; moto accepts any credentials
AWS_ENV = {"AWS_ACCESS_KEY_ID": "hmsm-test", "AWS_SECRET_ACCESS_KEY": "hmsm-test",
           "AWS_DEFAULT_REGION": "us-east-1"}


def _client(endpoint: str):  # type: ignore[no-untyped-def]
    return boto3.client("s3", endpoint_url=endpoint, region_name="us-east-1",
                        aws_access_key_id=AWS_ENV["AWS_ACCESS_KEY_ID"],
                        aws_secret_access_key=AWS_ENV["AWS_SECRET_ACCESS_KEY"])


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class MotoS3:
    def __init__(self) -> None:
        from moto.server import ThreadedMotoServer

        logging.getLogger("werkzeug").setLevel(logging.ERROR)  # a line per request otherwise
        self.port = _free_port()
        self.endpoint = f"http://127.0.0.1:{self.port}"
        self._server = ThreadedMotoServer(ip_address="127.0.0.1", port=self.port,
                                          verbose=False)
        self.running = False

    def start(self) -> None:
        self._server.start()
        self.running = True

    def stop(self) -> None:
        if self.running:
            self._server.stop()
            self.running = False

    def client(self):  # type: ignore[no-untyped-def]
        return _client(self.endpoint)

    def new_bucket(self) -> str:
        name = f"hmsm-{uuid.uuid4().hex[:16]}"
        self.client().create_bucket(Bucket=name)
        return name

    def keys(self, bucket: str) -> list[str]:
        return self.keys_at(self.endpoint, bucket)

    @staticmethod
    def keys_at(endpoint: str, bucket: str) -> list[str]:
        """The bucket's object keys on the S3 server at ``endpoint``."""
        listing = _client(endpoint).list_objects_v2(Bucket=bucket)
        return sorted(item["Key"] for item in listing.get("Contents", []))


class SilentServer:
    """A TCP server on a free loopback port that accepts every connection and never reads or
    answers: an object store that hangs. :meth:`close` closes the connections it holds."""

    def __init__(self) -> None:
        self._listener = socket.create_server(("127.0.0.1", 0), backlog=64)
        self._listener.settimeout(0.1)
        self.endpoint = f"http://127.0.0.1:{self._listener.getsockname()[1]}"
        self.accepted = 0
        self._held: list[socket.socket] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._accept, name="silent-s3", daemon=True)
        self._thread.start()

    def _accept(self) -> None:
        while not self._stop.is_set():
            try:
                conn, _ = self._listener.accept()
            except TimeoutError:
                continue
            except OSError:  # closed
                return
            self._held.append(conn)
            self.accepted += 1

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=5)
        self._listener.close()
        for conn in self._held:
            conn.close()
