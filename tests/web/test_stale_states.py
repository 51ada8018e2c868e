"""The pages once the facts have moved on, through the TestClient (the same claims as
``tests/browser/test_stale_states.py``, which needs /usr/bin/chromium): a failed unit shows no
life and the winglet-pair row names it; after a no-fault-found no fault mode, RUL or cone; the
class at raising and its later change; the model's alarm level on the confidence chart."""

from __future__ import annotations

from server.db import session_scope
from server.models import Injection
from server.services import station_faults
from server.web.routes import csrf_token
from tests.web.seed import add_alarm, seed_class_change, seed_results
from tests.web.test_honest_diagnosis import _figure
from tests.web.test_pages import sign_in


def test_a_failed_unit_shows_no_life_and_the_pair_row_names_it(app, client, keys, aircraft  # type: ignore[no-untyped-def]
                                                                ) -> None:
    factory = app.state.session_factory
    seed = seed_results(factory, tail=aircraft, position="WL1")
    add_alarm(factory, tail=aircraft, position="WL2", fault_mode="DMD", rul=40.0)
    with session_scope(factory) as s:
        station_faults.set_status(session=s, row=s.get(Injection, seed.injection_id),
                                                status="failed", failure_flight=71)
    sign_in(client, keys["admin"])
    page = client.get(f"/actuators/{seed.actuator_id}").text
    headline = page.split('id="rul-headline">')[1].split("</dd>")[0]
    assert "failed" in headline and "at least" not in headline
    assert 'id="median-rul">0 flights (failed)<' in page
    notice = page.split('id="pair-notice">')[1].split("</p>")[0]
    assert "WL1 (this drive) failed at flight 71" in notice and "does not tell" not in notice
    assert "server/services/urgency.py" not in page
    assert "Failed at flight 71: no life left" in _figure(page, "fig-hist")["layout"]["title"][
        "text"]

    inbox = client.get("/alarms").text
    row = inbox.split('class="alarm open pair"')[1].split("</tr>")[0]
    assert "WL1 failed at flight 71" in row and "does not tell" not in row
    assert 'data-label="Median RUL">0 (failed)<' in row
    n_rows = inbox.count('<tr id="alarm-')
    assert f'id="alarm-count">{n_rows} of {n_rows} alarms' in inbox


def test_no_fault_found_leaves_no_stale_fault_and_keeps_the_class_at_raising(  # type: ignore[no-untyped-def]
        app, client, keys, aircraft) -> None:
    factory = app.state.session_factory
    seed = seed_results(factory, tail=aircraft, position="WL1")
    seed_class_change(factory, seed, tail=aircraft)
    sign_in(client, keys["maintainer"])
    url = f"/actuators/{seed.actuator_id}"
    page = client.get(url).text
    levels = [t["y"][0] for t in _figure(page, "fig-confidence")["data"]
              if t.get("name", "").startswith("alarm level")]
    assert levels == [0.95]
    assert 'id="alarm-events"' in page and "raised as MTEL" in page
    assert "at least" in page.split('id="rul-headline">')[1].split("</dd>")[0]

    r = client.post(f"{url}/inspect", data={"work_order": "WO-2026-0901",
                                            "note": "rod end within limits",
                                            "csrf": csrf_token(keys["maintainer"])})
    assert r.status_code == 200, r.text  # followed the redirect to the page
    page = r.text
    assert 'id="fault-mode">–<' in page and 'id="rul-headline">–<' in page
    assert 'id="median-rul">–<' in page and 'id="no-prognosis"' in page
    cone = _figure(page, "fig-cone")
    assert not any(t.get("x") for t in cone["data"])
    own = page.split(f'id="own-alarm-{seed.alarm_id}"')[1].split("</tr>")[0]
    assert "no fault found" in own and "raised as" in own and ">MTEL<" in own
    trail = page.split('id="maintenance-trail"')[1].split("</tr>")[1]
    assert "WO-2026-0901" in trail and "raised as" in trail and ">MTEL<" in trail
