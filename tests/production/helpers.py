"""Helpers of the production tests: a fresh PostgreSQL database, a cuttable TCP proxy, polling,
a seeded system (keys, fleet, active model) and worker processes."""

from __future__ import annotations

import os
import select
import socket
import subprocess
import sys
import threading
import time
import uuid
from collections.abc import Callable, Iterator
from contextlib import contextmanager, suppress
from typing import Any

from sqlalchemy import create_engine, text

from server.auth import create_key
from server.config import Settings
from server.db import make_session_factory, session_scope
from server.migrate import upgrade
from server.models import ROLES
from server.services import models as model_service

__all__ = ["TcpProxy", "fresh_pg_database", "wait_until", "seed_system", "env_of",
           "worker_process", "ROLES"]



def _pg(url: str) -> str:
    return url.replace("postgresql://", "postgresql+psycopg://", 1) if url.startswith(
        "postgresql://") else url


@contextmanager
def fresh_pg_database(admin_url: str, prefix: str = "hmsm_prod") -> Iterator[str]:
    """A new, empty PostgreSQL database (plain ``postgresql://`` URL); dropped afterwards."""
    admin = create_engine(_pg(admin_url), isolation_level="AUTOCOMMIT")
    name = f"{prefix}_{uuid.uuid4().hex[:10]}"
    with admin.connect() as conn:
        conn.execute(text(f'CREATE DATABASE "{name}"'))
    base = admin_url.rpartition("/")[0]
    try:
        yield f"{base}/{name}"
    finally:
        with admin.connect() as conn:
            conn.execute(text(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)'))
        admin.dispose()


def wait_until(predicate: Callable[[], bool], timeout_s: float, what: str,
               every_s: float = 0.2) -> None:
    """Poll ``predicate`` until it holds; fail with ``what`` after ``timeout_s``."""
    deadline = time.monotonic() + timeout_s
    while not predicate():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {timeout_s:.0f} s waiting for {what}")
        time.sleep(every_s)


class TcpProxy:
    """A loopback TCP forwarder to ``target`` that a test can cut and restore.

    Cut: every open connection is closed and new ones are accepted then closed at once, so a
    PostgreSQL client sees exactly what a dead database host looks like from the application
    (connection lost / refused) -- while the real server keeps serving everybody else.
    """

    def __init__(self, target: tuple[str, int]):
        self.target = target
        self._listener = socket.create_server(("127.0.0.1", 0))
        self.port = int(self._listener.getsockname()[1])
        self._up = threading.Event()
        self._up.set()
        self._stop = threading.Event()
        self._lock = threading.Lock()
        self._conns: set[socket.socket] = set()
        self._thread = threading.Thread(target=self._accept_loop, daemon=True)
        self._thread.start()

    def _accept_loop(self) -> None:
        self._listener.settimeout(0.2)
        while not self._stop.is_set():
            try:
                client, _ = self._listener.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            if not self._up.is_set():
                client.close()
                continue
            try:
                upstream = socket.create_connection(self.target, timeout=5)
            except OSError:
                client.close()
                continue
            with self._lock:
                self._conns.update((client, upstream))
            threading.Thread(target=self._pump, args=(client, upstream), daemon=True).start()

    def _pump(self, a: socket.socket, b: socket.socket) -> None:
        try:
            while True:
                ready, _, _ = select.select([a, b], [], [], 0.5)
                if self._stop.is_set() or not self._up.is_set():
                    return
                for src in ready:
                    data = src.recv(65536)
                    if not data:
                        return
                    (b if src is a else a).sendall(data)
        except OSError:
            return
        finally:
            self._close(a, b)

    def _close(self, *socks: socket.socket) -> None:
        with self._lock:
            for s in socks:
                self._conns.discard(s)
                with suppress(OSError):
                    s.shutdown(socket.SHUT_RDWR)
                s.close()

    def cut(self) -> None:
        self._up.clear()
        with self._lock:
            conns = list(self._conns)
        self._close(*conns)

    def restore(self) -> None:
        self._up.set()

    def close(self) -> None:
        self._stop.set()
        self.cut()
        self._listener.close()
        self._thread.join(timeout=5)

    def url_for(self, pg_url: str) -> str:
        """``pg_url`` with its host:port replaced by the proxy's."""
        scheme, rest = pg_url.split("://", 1)
        userinfo, _, hostpath = rest.rpartition("@")
        path = hostpath.split("/", 1)[1]
        return f"{scheme}://{userinfo + '@' if userinfo else ''}127.0.0.1:{self.port}/{path}"


def env_of(settings: Settings) -> dict[str, str]:
    env = {"HMSM_DATA_DIR": str(settings.data_dir)}
    if settings.database_url:
        env["HMSM_DATABASE_URL"] = settings.database_url
    return env


def seed_system(settings: Settings, model_payload: dict[str, Any] | None = None
                ) -> dict[str, str]:
    """Schema at head, one key per role (plaintexts returned), the model active if given."""
    settings.data_dir.mkdir(parents=True, exist_ok=True)
    upgrade(settings.effective_database_url)
    engine = create_engine(settings.effective_database_url)
    try:
        with session_scope(make_session_factory(engine)) as s:
            if model_payload is not None:
                model_service.store_trained(session=s, name="production-tests",
                                            payload=model_payload, report={}, make_active=True)
            return {r: create_key(session=s, name=f"prod-{r}", role=r)[1] for r in ROLES}
    finally:
        engine.dispose()


@contextmanager
def worker_process(settings: Settings, *args: str) -> Iterator[subprocess.Popen[bytes]]:
    """``hmsm worker ARGS`` as a process on these settings; SIGTERM (then SIGKILL) at the end."""
    proc = subprocess.Popen([sys.executable, "-m", "server.cli", "worker", *args],
                            env={**os.environ, **env_of(settings)},
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        yield proc
    finally:
        if proc.poll() is None:
            proc.terminate()
            try:
                proc.wait(timeout=60)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(timeout=10)
