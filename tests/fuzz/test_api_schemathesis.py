"""Schemathesis against the app's own OpenAPI schema, with an admin key so that every write
is exercised: no request, however malformed, may produce a 5xx.

Bounded: at most ``MAX_EXAMPLES`` cases per operation, no deadline (the app runs in-process
on a SQLite file), so the whole module stays around a minute.
"""

from __future__ import annotations

from collections.abc import Iterator

import pytest

schemathesis = pytest.importorskip("schemathesis")

from hypothesis import HealthCheck, settings  # noqa: E402
from schemathesis.checks import not_a_server_error  # noqa: E402

from server.app import create_app  # noqa: E402
from server.config import Settings  # noqa: E402
from server.db import make_engine, make_session_factory, session_scope  # noqa: E402
from server.models import ApiKey  # noqa: E402
from tests.flightlog_factory import serials_for  # noqa: E402

MAX_EXAMPLES = 25
# The fuzzing key has an id the generated path parameters are unlikely to hit, so that
# ``POST /keys/{id}/revoke`` cannot lock the fuzzer out half-way.
FUZZ_KEY_ID = 987_654_321


@pytest.fixture(scope="module")
def fuzz_app(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[object, str]]:
    from server.auth import KEY_PREFIX, hash_key

    settings = Settings(data_dir=tmp_path_factory.mktemp("fuzz") / "data",
                        max_upload_bytes=2 * 1024 * 1024)
    app = create_app(settings)
    plaintext = KEY_PREFIX + "fuzz-admin-key-for-schemathesis-only-0123456789"
    engine = make_engine(settings.effective_database_url)
    with session_scope(make_session_factory(engine)) as s:
        s.add(ApiKey(id=FUZZ_KEY_ID, name="fuzz", role="admin", key_hash=hash_key(plaintext),
                     prefix=plaintext[:10]))
    engine.dispose()
    from fastapi.testclient import TestClient

    with TestClient(app) as client:  # a little data so that ids can hit real rows
        h = {"Authorization": f"Bearer {plaintext}"}
        for tail in ("FZ1", "FZ2"):
            assert client.post("/api/v1/aircraft", headers=h, json={
                "tail": tail, "base": "Turin", "actuators": serials_for(tail)}).status_code == 201
    yield app, plaintext


@pytest.fixture(scope="module")
def api_schema(fuzz_app):  # type: ignore[no-untyped-def]
    app, key = fuzz_app
    return schemathesis.openapi.from_asgi("/openapi.json", app,
                                          headers={"Authorization": f"Bearer {key}"})


def _operations(schema):  # type: ignore[no-untyped-def]
    for result in schema.get_all_operations():
        operation = result.ok()
        if operation.path == "/api/v1/events":  # server-sent events: an endless stream
            continue
        yield operation


@pytest.mark.slow
def test_no_server_errors_on_any_operation(api_schema, fuzz_app) -> None:  # type: ignore[no-untyped-def]
    """Every operation, ``MAX_EXAMPLES`` generated cases each; collect every 5xx, then fail."""
    from hypothesis import given

    _, key = fuzz_app
    headers = {"Authorization": f"Bearer {key}"}
    failures: list[str] = []
    operations = list(_operations(api_schema))
    assert len(operations) >= 25, [op.label for op in operations]
    for operation in operations:
        @given(case=operation.as_strategy())
        @settings(max_examples=MAX_EXAMPLES, deadline=None, derandomize=True, database=None,
                  suppress_health_check=list(HealthCheck))
        def run(case) -> None:  # type: ignore[no-untyped-def]
            case.call_and_validate(headers=headers, checks=[not_a_server_error])

        try:
            run()
        except Exception as exc:  # one report per operation, the rest keep running
            failures.append(f"{operation.label}: {str(exc)[:2000]}")
    assert not failures, "\n\n".join(failures)
