"""The test-station page lists sensor injections (issue 45) and an operator cancels one, on a
390 px phone: nothing scrolls sideways, the status and the cancel button are on the screen; a
viewer sees no cancel button and a forged cancel is refused. Real browser and server, as
tests/browser/test_dashboard.py (whose fixtures it shares)."""

from __future__ import annotations

import re

import httpx

from tests.browser.test_dashboard import (  # noqa: F401  (fixtures)
    PHONE,
    Console,
    Live,
    _in_viewport,
    _shot,
    _sign_in,
    browser,
    live,
    pytestmark,
)


def _inject(live: Live) -> int:  # noqa: F811
    r = httpx.post(f"{live.url}/api/v1/test-station/sensor-injections",
                   headers={"Authorization": f"Bearer {live.keys['operator']}"},
                   json={"aircraft": live.tails[2], "position": "WT", "sensor": "lvdt",
                         "kind": "noise", "value": 3, "onset_flight": 5}, timeout=30)
    assert r.status_code == 201, r.text
    return int(r.json()["id"])


def test_sensor_injections_listed_and_cancelled_on_a_phone(live: Live, browser) -> None:  # type: ignore[no-untyped-def]  # noqa: F811
    injection = _inject(live)
    viewer = browser.new_context(viewport=PHONE)
    page = viewer.new_page()
    _sign_in(page, live.url, live.keys["viewer"])
    page.goto(f"{live.url}/test-station")
    row = page.locator(f"#sensor-injection-{injection}")
    assert "noise 3" in row.inner_text() and row.get_by_role("button").count() == 0
    r = viewer.request.post(f"{live.url}/test-station/sensor-injections/{injection}/cancel",
                            form={"csrf": "x"})
    assert r.status == 403
    viewer.close()

    context = browser.new_context(viewport=PHONE)
    page = context.new_page()
    console = Console(page)
    _sign_in(page, live.url, live.keys["operator"])
    page.goto(f"{live.url}/test-station")
    overflow = page.evaluate("""() => [document.documentElement,
        document.querySelector('#sensor-injection-table').parentElement]
        .map(e => e.scrollWidth - e.clientWidth)""")
    assert overflow == [0, 0], overflow  # page, table box
    row = page.locator(f"#sensor-injection-{injection}")
    row.scroll_into_view_if_needed()
    _shot(page, "test-station-sensors-390")
    assert "pending" in row.inner_text() and "WT" in row.inner_text()
    for cell in (row.locator('td[data-label="Status"]'), row.get_by_role("button")):
        box = cell.bounding_box()
        assert box is not None and box["x"] >= 0 and box["x"] + box["width"] <= PHONE["width"]
    button = row.get_by_role("button", name=re.compile("^Cancel sensor injection"))
    button.scroll_into_view_if_needed()
    assert button.is_visible() and _in_viewport(page, button)
    button.click()
    page.wait_for_url(f"{live.url}/test-station")
    assert "cancelled" in page.locator(f"#sensor-injection-{injection}").inner_text()
    assert page.locator(f"#sensor-injection-{injection}").get_by_role("button").count() == 0
    r = httpx.get(f"{live.url}/api/v1/test-station/sensor-injections/{injection}",
                  headers={"Authorization": f"Bearer {live.keys['viewer']}"}, timeout=30)
    assert r.json()["status"] == "cancelled"
    assert console.errors == [], console.errors
    context.close()


def _listed(live: Live, tail: str) -> list[dict[str, object]]:  # noqa: F811
    r = httpx.get(f"{live.url}/api/v1/test-station/sensor-injections",
                  params={"aircraft": tail},
                  headers={"Authorization": f"Bearer {live.keys['viewer']}"}, timeout=30)
    return list(r.json()["items"])


def test_an_operator_degrades_a_sensor_from_the_form_on_a_phone(live: Live, browser) -> None:  # type: ignore[no-untyped-def]  # noqa: F811
    tail = live.tails[1]
    viewer = browser.new_context(viewport=PHONE)
    page = viewer.new_page()
    _sign_in(page, live.url, live.keys["viewer"])
    page.goto(f"{live.url}/test-station")
    assert page.locator("#sensor-form").count() == 0 and page.locator("#no-inject").is_visible()
    r = viewer.request.post(f"{live.url}/test-station/sensor-injections", form={
        "csrf": "x", "aircraft": tail, "position": "WL2", "sensor": "current", "kind": "noise",
        "value": "3"})
    assert r.status == 403
    viewer.close()

    context = browser.new_context(viewport=PHONE)
    page = context.new_page()
    console = Console(page)
    _sign_in(page, live.url, live.keys["operator"])
    r = context.request.post(f"{live.url}/test-station/sensor-injections", form={
        "aircraft": tail, "position": "WL2", "sensor": "current", "kind": "noise",
        "value": "3"})  # the session, no CSRF token
    assert r.status == 403
    page.goto(f"{live.url}/test-station")
    form = page.locator("#sensor-form")
    form.get_by_label("Aircraft").select_option(tail)
    form.get_by_label("Position").select_option("WL2")
    form.get_by_label("Sensor").select_option("current")
    form.get_by_label("Kind").select_option("noise")
    form.get_by_label("Value").fill("80")
    form.get_by_label("Start flight").fill("7")
    form.get_by_role("button", name="Degrade sensor").click()
    error = page.locator("#sensor-error")
    error.wait_for()
    assert "noise factor must be above 1 and at most 50" in error.inner_text()
    assert _listed(live, tail) == []
    assert _in_viewport(page, error)  # the page came back scrolled to its form
    form = page.locator("#sensor-form")
    assert form.get_by_label("Value").input_value() == "80"  # kept, to correct
    overflow = page.evaluate("""() => [document.documentElement,
        document.querySelector('#sensor-form')].map(e => e.scrollWidth - e.clientWidth)""")
    assert overflow == [0, 0], overflow  # page, form
    for field in ("Aircraft", "Kind", "Value", "Start flight"):
        box = form.get_by_label(field).bounding_box()
        assert box is not None and box["x"] >= 0 and box["x"] + box["width"] <= PHONE["width"]
    form.scroll_into_view_if_needed()
    _shot(page, "test-station-sensor-form-390")
    form.get_by_label("Value").fill("3")
    form.get_by_role("button", name="Degrade sensor").click()
    page.wait_for_url(re.compile(r"/test-station(#sensor-form)?$"))
    [made] = _listed(live, tail)
    assert (made["sensor"], made["kind"], made["value"], made["onset_flight"]) == (
        "current", "noise", 3, 7)
    row = page.locator(f"#sensor-injection-{made['id']}")
    assert "noise 3" in row.inner_text() and "pending" in row.inner_text()
    # the refused post's page came with its 422, which the browser logs; nothing else
    assert [e for e in console.errors if "status of 422" not in e] == [], console.errors
    context.close()
