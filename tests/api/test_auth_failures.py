"""Failed authentications are limited per presented key and per client address
(``server/ratelimit.py``): API keys, the session cookie and the sign-in form alike, 429 with
``Retry-After`` for a wrong key past either budget, a right key never refused, successes never
counted, the number of tracked addresses and keys bounded."""

from __future__ import annotations

import pytest
from fastapi.testclient import TestClient

from server.app import create_app
from server.auth import create_key
from server.db import session_scope
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
    # past the address's budget its wrong keys are 429, a new one too (looked up first), while
    # a right key is served: another key's failures never refuse it
    r = client.get("/api/v1/flights", headers=auth("hmsm_" + "z" * 43))
    assert r.status_code == 429 and "from this address" in r.json()["error"]["message"]
    assert client.get("/api/v1/flights", headers=auth(keys["viewer"])).status_code == 200
    assert client.get("/api/v1/health/live").status_code == 200  # no key: never limited
    other = TestClient(app, client=("192.0.2.7", 40000))  # another address has its own budget
    assert other.get("/api/v1/flights", headers=auth(keys["viewer"])).status_code == 200
    assert other.get("/api/v1/flights", headers=auth("hmsm_" + "z" * 43)).status_code == 401
    r = other.get("/api/v1/flights", headers=auth(WRONG))  # but the key spent its own budget
    assert r.status_code == 429 and "with this key" in r.json()["error"]["message"]


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
    r = client.post("/signin", data={"key": "hmsm_" + "z" * 43, "next": "/fleet",
                                     "csrf": signin_token(client)})
    assert r.status_code == 429 and r.headers["Retry-After"]
    assert "set-cookie" not in r.headers
    assert sign_in(client, keys["viewer"]).status_code == 303  # a right key signs in


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


# ------------------------------------------------------------------------------------------
# a neighbour's failures never refuse a right key (issue 57): everyone behind one NAT, or
# every user when a reverse proxy sits outside FORWARDED_ALLOW_IPS, shares one address
# ------------------------------------------------------------------------------------------

NEIGHBOURS = ("198.51.100.7", 40000)  # the user and the attacker: one address


@pytest.mark.parametrize("wrong_keys", ["one_key", "a_new_key_each_second"])
def test_a_neighbour_failing_once_a_second_never_locks_out_a_right_key(
        settings, wrong_keys: str) -> None:  # type: ignore[no-untyped-def]
    """The measured lock-out replayed in simulated time: one wrong key a second from the
    user's address (for a minute before the user comes, then for 40 s beside the user's two
    requests a second). Before per-key budgets the address's budget refused the user too: 65
    of 80 requests measured on a live server, all 80 in this replay (whose clock does not
    jitter: the attacker's request always takes the refilled failure first)."""
    now = [0.0]
    app = create_app(settings, clock=lambda: now[0])
    with session_scope(app.state.session_factory) as session:
        right = create_key(session=session, name="user", role="viewer")[1]
    user: list[int] = []
    attacker: list[tuple[float, int, str | None]] = []
    with TestClient(app, client=NEIGHBOURS) as client:
        for step in range(200):  # 100 s in half seconds
            now[0] = step * 0.5
            if step % 2 == 0:
                wrong = WRONG if wrong_keys == "one_key" else f"hmsm_{step:043d}"
                r = client.get("/api/v1/flights", headers=auth(wrong))
                attacker.append((now[0], r.status_code, r.headers.get("retry-after")))
            if now[0] >= 60:
                user.append(client.get("/api/v1/flights", headers=auth(right)).status_code)
    app.state.engine.dispose()
    refused = sum(code != 200 for code in user)
    assert len(user) == 80 and refused == 0, f"the right key refused {refused} of {len(user)}"
    # the attacker: its budget's worth checked (401), then slowed: 429 with Retry-After for
    # as long as it goes on without waiting
    assert [code for _, code, _ in attacker[:BUDGET]] == [401] * BUDGET
    late = [(t, code, wait) for t, code, wait in attacker if t >= 60]
    assert len(late) == 40 and all(code == 429 and wait and int(wait) >= 1
                                   for _, code, wait in late), late


def test_a_right_key_signs_in_through_the_form_from_an_address_past_its_budget(
        app, client: TestClient, keys: dict[str, str]) -> None:  # type: ignore[no-untyped-def]
    for i in range(BUDGET):  # the neighbour's wrong keys, each a new one
        assert client.get("/api/v1/flights",
                          headers=auth(f"hmsm_{i:043d}")).status_code == 401
    assert client.get("/api/v1/flights", headers=auth(WRONG)).status_code == 429
    assert sign_in(client, WRONG).status_code == 429  # the form's wrong key: slowed too
    r = sign_in(client, keys["viewer"])
    assert r.status_code == 303 and "hmsm_session" in r.headers["set-cookie"], r.text[:300]
    assert client.get("/fleet", follow_redirects=False).status_code == 200  # the cookie
    assert client.get("/metrics", headers=auth(keys["admin"])).status_code == 200


def test_one_wrong_key_is_limited_from_every_address(app, keys: dict[str, str]) -> None:  # type: ignore[no-untyped-def]
    """A key's own budget: the same wrong (or revoked) key from many addresses, e.g. a fleet
    of clients left with an old key, is refused past the budget wherever it comes from."""
    codes = []
    for i in range(BUDGET + 5):
        with TestClient(app, client=(f"192.0.2.{i + 1}", 40000)) as other:
            codes.append(other.get("/api/v1/flights", headers=auth(WRONG)).status_code)
            if i == BUDGET + 4:  # that address's own budget is whole: other keys are checked
                assert other.get("/api/v1/flights",
                                 headers=auth("hmsm_" + "y" * 43)).status_code == 401
                assert other.get("/api/v1/flights",
                                 headers=auth(keys["viewer"])).status_code == 200
    assert codes == [401] * BUDGET + [429] * 5
