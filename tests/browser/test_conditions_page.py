"""Issue 45 on a 390 px phone: the test-station page lists a condition beside the fault and
sensor injections and an operator cancels it (nothing scrolls sideways, the status and the
button are on the screen; a viewer sees no button and a forged cancel is refused); the
actuator page shades the flights flown under it on its feature charts and names it beside
what it moves. Real browser and server, as tests/browser/test_dashboard.py (whose fixtures it
shares)."""

from __future__ import annotations

import re

import httpx

from tests.browser.test_dashboard import (  # noqa: F401  (fixtures)
    PHONE,
    Console,
    Live,
    _in_viewport,
    _plot_points,
    _shot,
    _sign_in,
    browser,
    live,
    pytestmark,
)

URL = "/api/v1/test-station/conditions"


def _api(live: Live, method: str, path: str, **kwargs: object) -> httpx.Response:  # noqa: F811
    return httpx.request(method, f"{live.url}{path}", timeout=30, headers={
        "Authorization": f"Bearer {live.keys['operator']}"}, **kwargs)  # type: ignore[arg-type]


def _hot_flights_30_to_35(live: Live) -> int:  # noqa: F811
    """+15 K on the seeded aircraft, reported (as the sim worker would) on its flights 30-35."""
    r = _api(live, "POST", URL, json={"aircraft": live.tails[0], "kind": "ambient_offset",
                                      "value": 15, "onset_flight": 30})
    assert r.status_code == 201, r.text
    cid = int(r.json()["id"])
    for n in range(30, 36):
        r = _api(live, "PUT", f"{URL}/{cid}/ground-truth",
                 json={"flight": f"F{n:04d}", "flight_number": n, "applied": 15})
        assert r.status_code == 200, r.text
    return cid


def test_a_condition_listed_cancelled_and_marked_on_a_phone(live: Live, browser) -> None:  # type: ignore[no-untyped-def]  # noqa: F811
    cid = _hot_flights_30_to_35(live)
    # a noisy LVDT on the seeded drive, reported on its flights 38-40
    sensor = _api(live, "POST", "/api/v1/test-station/sensor-injections", json={
        "aircraft": live.tails[0], "position": "WL1", "sensor": "lvdt", "kind": "noise",
        "value": 3, "onset_flight": 38})
    assert sensor.status_code == 201, sensor.text
    for n in range(38, 41):
        r = _api(live, "PUT", f"/api/v1/test-station/sensor-injections/{sensor.json()['id']}"
                 "/ground-truth", json={"flight": f"F{n:04d}", "flight_number": n, "applied": 3})
        assert r.status_code == 200, r.text

    viewer = browser.new_context(viewport=PHONE)
    page = viewer.new_page()
    _sign_in(page, live.url, live.keys["viewer"])
    page.goto(f"{live.url}/test-station")
    row = page.locator(f"#condition-{cid}")
    assert "ambient_offset 15" in row.inner_text() and row.get_by_role("button").count() == 0
    r = viewer.request.post(f"{live.url}/test-station/conditions/{cid}/cancel",
                            form={"csrf": "x"})
    assert r.status == 403
    viewer.close()

    context = browser.new_context(viewport=PHONE)
    page = context.new_page()
    console = Console(page)
    _sign_in(page, live.url, live.keys["operator"])
    page.goto(f"{live.url}/test-station")
    # the three kinds on one page: fault injections (the seed's DMD), sensor, condition
    for table in ("#injection-table", "#sensor-injection-table", "#condition-table"):
        assert page.locator(f"{table} tbody tr").first.get_by_role("cell").count() > 1, table
    overflow = page.evaluate("""() => [document.documentElement,
        document.querySelector('#condition-table').parentElement]
        .map(e => e.scrollWidth - e.clientWidth)""")
    assert overflow == [0, 0], overflow  # page, table box
    row = page.locator(f"#condition-{cid}")
    row.scroll_into_view_if_needed()
    _shot(page, "test-station-conditions-390")
    text = row.inner_text()
    assert "active\nfrom 30" in text and "6 flights; last F0035: 15" in text, text
    for cell in (row.locator('td[data-label="Status"]'), row.get_by_role("button")):
        box = cell.bounding_box()
        assert box is not None and box["x"] >= 0 and box["x"] + box["width"] <= PHONE["width"]
    button = row.get_by_role("button", name=re.compile("^Cancel condition"))
    button.scroll_into_view_if_needed()
    assert button.is_visible() and _in_viewport(page, button)
    button.click()
    page.wait_for_url(f"{live.url}/test-station")
    assert "cancelled" in page.locator(f"#condition-{cid}").inner_text()
    assert page.locator(f"#condition-{cid}").get_by_role("button").count() == 0
    assert _api(live, "GET", f"{URL}/{cid}").json()["status"] == "cancelled"

    # the actuator page: flights 30-35 shaded on the feature charts, the condition named
    page.goto(f"{live.url}/actuators/{live.seed.actuator_id}")
    assert _plot_points(page, "fig-trends")
    shaded = page.evaluate("""id => (document.getElementById(id).layout.shapes || [])
        .filter(s => s.type === 'rect' && s.xref === 'x').map(s => [s.x0, s.x1])""",
                           "fig-trends")
    marks = page.locator("#station-marks")
    marks.scroll_into_view_if_needed()
    _shot(page, "actuator-station-marks-390")
    hot = marks.locator("tbody tr", has_text="ambient_offset 15")
    assert hot.count() == 1, marks.inner_text()
    assert all(s in hot.inner_text() for s in ("30–35", "fault DMD", "T_amb")), hot.inner_text()
    noisy = marks.locator("tbody tr", has_text="lvdt noise 3")
    assert noisy.count() == 1 and "38–40" in noisy.inner_text() and "WL1.x" in noisy.inner_text()
    # one band per run of flights with the same things live: DMD from its onset (the seed's),
    # +15 K on 30-35, DMD alone on 36-37, DMD and the noisy LVDT on 38-40
    assert shaded == [[14.5, 29.5], [29.5, 35.5], [35.5, 37.5], [37.5, 40.5]], shaded
    assert page.evaluate("() => document.documentElement.scrollWidth - "
                         "document.documentElement.clientWidth") == 0
    assert console.errors == [], console.errors
    context.close()


def test_an_operator_sets_conditions_from_the_form_on_a_phone(live: Live, browser) -> None:  # type: ignore[no-untyped-def]  # noqa: F811
    tail = live.tails[1]
    viewer = browser.new_context(viewport=PHONE)
    page = viewer.new_page()
    _sign_in(page, live.url, live.keys["viewer"])
    page.goto(f"{live.url}/test-station")
    assert page.locator("#condition-form").count() == 0
    r = viewer.request.post(f"{live.url}/test-station/conditions", form={
        "csrf": "x", "aircraft": tail, "kind": "load_scale", "value": "1.5"})
    assert r.status == 403
    viewer.close()

    context = browser.new_context(viewport=PHONE)
    page = context.new_page()
    console = Console(page)
    _sign_in(page, live.url, live.keys["operator"])
    r = context.request.post(f"{live.url}/test-station/conditions", form={
        "aircraft": tail, "kind": "load_scale", "value": "1.5"})  # the session, no CSRF token
    assert r.status == 403
    page.goto(f"{live.url}/test-station")
    form = page.locator("#condition-form")
    form.get_by_label("Aircraft").select_option(tail)
    form.get_by_label("Kind").select_option("load_scale")
    form.get_by_label("Value").fill("4")
    form.get_by_role("button", name="Set condition").click()
    error = page.locator("#condition-error")
    error.wait_for()
    assert "load_scale must be above 0 and at most 3" in error.inner_text()
    assert _in_viewport(page, error)  # the page came back scrolled to its form
    assert _api(live, "GET", URL, params={"aircraft": tail}).json()["items"] == []
    overflow = page.evaluate("""() => [document.documentElement,
        document.querySelector('#condition-form')].map(e => e.scrollWidth - e.clientWidth)""")
    assert overflow == [0, 0], overflow  # page, form
    form = page.locator("#condition-form")
    for field in ("Aircraft", "Kind", "Value", "Base", "Start flight"):
        box = form.get_by_label(field).bounding_box()
        assert box is not None and box["x"] >= 0 and box["x"] + box["width"] <= PHONE["width"]
    form.scroll_into_view_if_needed()
    _shot(page, "test-station-condition-form-390")
    form.get_by_label("Value").fill("1.5")
    form.get_by_role("button", name="Set condition").click()
    page.wait_for_url(re.compile(r"/test-station(#condition-form)?$"))
    # a base: no value, one of the vocabulary's bases
    form = page.locator("#condition-form")
    form.get_by_label("Aircraft").select_option(tail)
    form.get_by_label("Kind").select_option("base")
    form.get_by_label("Base").select_option("Vancouver")
    form.get_by_label("Start flight").fill("12")
    form.get_by_role("button", name="Set condition").click()
    page.wait_for_url(re.compile(r"/test-station(#condition-form)?$"))
    made = {c["kind"]: c for c in _api(live, "GET", URL, params={"aircraft": tail}
                                       ).json()["items"]}
    assert (made["load_scale"]["value"], made["load_scale"]["onset_flight"]) == (1.5, 0)
    assert (made["base"]["base"], made["base"]["onset_flight"]) == ("Vancouver", 12)
    for c, what in ((made["load_scale"], "load_scale 1.5"), (made["base"], "base Vancouver")):
        row = page.locator(f"#condition-{c['id']}")
        assert what in row.inner_text() and "pending" in row.inner_text()
    # one live per kind: the service's 409, on the page
    form = page.locator("#condition-form")
    form.get_by_label("Aircraft").select_option(tail)
    form.get_by_label("Kind").select_option("load_scale")
    form.get_by_label("Value").fill("2")
    form.get_by_role("button", name="Set condition").click()
    page.locator("#condition-error").wait_for()
    assert "already has a live load_scale condition" in page.locator(
        "#condition-error").inner_text()
    # the refused posts' pages came with their 422 and 409, which the browser logs
    assert [e for e in console.errors if not re.search("status of (422|409)", e)] == [], \
        console.errors
    context.close()
