"""Failed authentications are limited per client address (``server/ratelimit.py``): API keys
and the sign-in form alike, 429 with ``Retry-After`` past the budget, successes never counted,
the number of tracked addresses bounded."""

from __future__ import annotations

from fastapi.testclient import TestClient

from server.ratelimit import FailureBudget
from tests.api.conftest import auth
from tests.signin import sign_in, signin_token

WRONG = "hmsm_" + "x" * 43
BUDGET = 20  # the default HMSM_AUTH_FAILURES_PER_MINUTE


def test_wrong_keys_past_the_budget_answer_429_with_retry_after(app, client: TestClient,
                                                                keys: dict[str, str]) -> None:
    assert app.state.settings.auth_failures_per_minute == BUDGET
    for _ in range(BUDGET):
        assert client.get("/api/v1/flights", headers=auth(WRONG)).status_code == 401
    r = client.get("/api/v1/flights", headers=auth(WRONG))
    assert r.status_code == 429, r.text
    assert r.json()["error"]["code"] == "too_many_failures"
    assert 1 <= int(r.headers["Retry-After"]) <= 60 // BUDGET + 1
    # until a failure is refilled the address presents no key at all, not even a right one:
    # otherwise 429 and 200 would still tell a guess from a hit at full speed
    assert client.get("/api/v1/flights", headers=auth(keys["viewer"])).status_code == 429
    assert client.get("/api/v1/health/live").status_code == 200  # no key: never limited
    other = TestClient(app, client=("192.0.2.7", 40000))  # another address has its own budget
    assert other.get("/api/v1/flights", headers=auth(keys["viewer"])).status_code == 200
    assert other.get("/api/v1/flights", headers=auth(WRONG)).status_code == 401


def test_successful_requests_are_never_counted(client: TestClient, keys: dict[str, str]) -> None:
    for _ in range(3 * BUDGET):
        assert client.get("/api/v1/aircraft", headers=auth(keys["viewer"])).status_code == 200
    for _ in range(BUDGET):  # the whole budget is still there
        assert client.get("/api/v1/aircraft", headers=auth(WRONG)).status_code == 401


def test_signin_form_and_session_cookie_share_the_budget(app, client: TestClient,
                                                         keys: dict[str, str]) -> None:
    guessed = TestClient(app, cookies={"hmsm_session": WRONG})  # the same address
    for i in range(BUDGET):
        if i % 2:
            r = sign_in(client, WRONG)
            assert r.status_code == 401, r.text
        else:  # a guessed cookie on a dashboard page: sent to the sign-in page
            r = guessed.get("/fleet", follow_redirects=False)
            assert r.status_code == 303 and r.headers["location"].startswith("/signin?next=")
    r = client.post("/signin", data={"key": keys["viewer"], "next": "/fleet",
                                     "csrf": signin_token(client)})
    assert r.status_code == 429 and r.headers["Retry-After"]
    assert "set-cookie" not in r.headers


def test_budget_refills_and_tracks_a_bounded_number_of_addresses() -> None:
    now = [0.0]
    budget = FailureBudget(per_minute=20, max_clients=100, clock=lambda: now[0])
    for _ in range(20):
        assert budget.wait_s("a") == 0
        budget.failed("a")
    assert budget.wait_s("a") == 3.0  # one failure back every 60/20 s
    now[0] += 3.0
    assert budget.wait_s("a") == 0
    budget.failed("a")
    assert budget.wait_s("a") == 3.0
    for i in range(10_000):  # addresses rotated by an attacker: memory stays bounded
        budget.failed(f"10.0.{i // 256}.{i % 256}")
    assert len(budget) == 100
    assert budget.wait_s("a") == 0  # forgotten, the least recent failure


def test_limit_is_configurable_and_can_be_turned_off(settings) -> None:  # type: ignore[no-untyped-def]
    from server.app import create_app

    for per_minute, answers in ((2, [401, 401, 429]), (0, [401] * 30)):
        app = create_app(settings.model_copy(update={"auth_failures_per_minute": per_minute}))
        with TestClient(app) as client:
            got = [client.get("/api/v1/flights", headers=auth(WRONG)).status_code
                   for _ in answers]
        app.state.engine.dispose()
        assert got == answers
