"""Dashboard fixtures: the API fixtures (app, client, one key per role) and a signed-in client."""

from __future__ import annotations

from tests.api.conftest import active_model, aircraft, app, client, keys  # noqa: F401  (re-exported fixtures)
