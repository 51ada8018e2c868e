"""``hmsm serve`` against slow clients, over loopback: a stalled request body is cut with 408,
an idle keep-alive connection is closed, headers still coming past 16 KiB are refused, and
connections beyond the limit get 503 instead of holding the server (uvicorn has no header
timeout)."""

from __future__ import annotations

import socket
import time
from collections.abc import Iterator
from contextlib import closing, contextmanager

import pytest

from tests.live_server import running_server

LIMITS = {"HMSM_BODY_IDLE_TIMEOUT_S": "1", "HMSM_KEEP_ALIVE_S": "1",
          "HMSM_MAX_CONNECTIONS": "8"}


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[str, int]]:
    data_dir = tmp_path_factory.mktemp("slow") / "data"
    with running_server({"HMSM_DATA_DIR": str(data_dir), **LIMITS}) as url:
        host, port = url.removeprefix("http://").split(":")
        yield host, int(port)


@contextmanager
def connection(server: tuple[str, int]) -> Iterator[socket.socket]:
    with closing(socket.create_connection(server, timeout=5)) as sock:
        yield sock


def _read_until_closed(sock: socket.socket) -> bytes:
    data = b""
    while chunk := sock.recv(65536):
        data += chunk
    return data


def test_a_stalled_body_is_cut_with_408(server) -> None:  # type: ignore[no-untyped-def]
    with connection(server) as sock:
        sock.sendall(b"POST /api/v1/aircraft HTTP/1.1\r\nHost: x\r\n"
                     b"Content-Type: application/json\r\nContent-Length: 100\r\n\r\n{")
        started = time.monotonic()
        answer = _read_until_closed(sock)
    assert answer.startswith(b"HTTP/1.1 408"), answer[:200]
    assert b"request_timeout" in answer
    assert time.monotonic() - started < 4


def test_an_idle_keep_alive_connection_is_closed(server) -> None:  # type: ignore[no-untyped-def]
    with connection(server) as sock:
        sock.sendall(b"GET /api/v1/health/live HTTP/1.1\r\nHost: x\r\n\r\n")
        first = b""
        while not first.endswith(b'{"status":"ok"}'):
            first += sock.recv(65536)
        assert first.startswith(b"HTTP/1.1 200"), first[:200]
        started = time.monotonic()
        assert _read_until_closed(sock) == b""
    assert time.monotonic() - started < 4


def test_headers_still_coming_past_16_kib_are_refused(server) -> None:  # type: ignore[no-untyped-def]
    with connection(server) as sock:  # no blank line yet: the server buffers at most 16 KiB
        sock.sendall(b"GET /api/v1/health/live HTTP/1.1\r\nHost: x\r\nX-Pad: "
                     + b"a" * 20_000)
        answer = _read_until_closed(sock)
    assert answer.startswith(b"HTTP/1.1 4"), answer[:200]


def test_connections_beyond_the_limit_get_503(server) -> None:  # type: ignore[no-untyped-def]
    idle = [socket.create_connection(server, timeout=5) for _ in range(8)]
    try:
        with connection(server) as sock:
            sock.sendall(b"GET /api/v1/health/live HTTP/1.1\r\nHost: x\r\n"
                         b"Connection: close\r\n\r\n")
            answer = _read_until_closed(sock)
        assert answer.startswith(b"HTTP/1.1 503"), answer[:200]
    finally:
        for sock in idle:
            sock.close()
    time.sleep(0.3)  # the server notices the closed ones
    with connection(server) as sock:
        sock.sendall(b"GET /api/v1/health/live HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n")
        assert _read_until_closed(sock).startswith(b"HTTP/1.1 200")
