"""API fixtures: the app on the chosen backend, a client, and one key per role."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from fastapi.testclient import TestClient

from server.app import create_app
from server.auth import create_key
from server.config import Settings
from server.db import session_scope
from server.models import ROLES
from tests.flightlog_factory import serials_for


@pytest.fixture
def app(settings: Settings):  # type: ignore[no-untyped-def]
    app = create_app(settings)
    yield app
    app.state.engine.dispose()


@pytest.fixture
def client(app) -> Iterator[TestClient]:  # type: ignore[no-untyped-def]
    with TestClient(app, raise_server_exceptions=False) as c:
        yield c


@pytest.fixture
def keys(app) -> dict[str, str]:  # type: ignore[no-untyped-def]
    out = {}
    with session_scope(app.state.session_factory) as session:
        for role in ROLES:
            out[role] = create_key(session=session, name=f"test-{role}", role=role)[1]
    return out


def auth(key: str) -> dict[str, str]:
    return {"Authorization": f"Bearer {key}"}


@pytest.fixture
def aircraft(client: TestClient, keys: dict[str, str]) -> str:
    tail = "T001"
    r = client.post("/api/v1/aircraft", headers=auth(keys["admin"]),
                    json={"tail": tail, "base": "Turin", "actuators": serials_for(tail)})
    assert r.status_code == 201, r.text
    return tail


@pytest.fixture
def active_model(app, shipped_model) -> None:  # type: ignore[no-untyped-def]
    """The shipped chain stored in this app's database as the active model."""
    from server.services import models as model_service

    with app.state.session_factory() as session:
        model_service.store_trained(session=session, name="t", payload=shipped_model[0],
                                    report=shipped_model[1], make_active=True)
        session.commit()
