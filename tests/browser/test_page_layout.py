"""What the pages show a user at a desktop's 1280 px and a phone's 390 px (issue 57, "What a
user hits now"): a unit whose 5 % RUL quantile is under one flight reads "replace now" (due
now), never "act within 0 flights"; on every chart of the actuator page the title is neither
under plotly's mode bar nor cut at the figure's edge, and the legend lies inside the figure,
clear of the x axis title; a browser asking for /openapi.json without a key is sent to sign
in, and back to the schema.

Debian's /usr/bin/chromium driven by Playwright against ``hmsm serve``, with the fixtures of
``test_dashboard.py`` (a server of this module's own)."""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any

import pytest

from server.models import Injection
from server.services import station_faults
from tests.browser.test_dashboard import (  # noqa: F401  (fixtures of this module's own)
    Console,
    Live,
    _shot,
    _sign_in,
    browser,
    live,
    pytestmark,
)
from tests.web.seed import seed_results

WIDTHS = [pytest.param({"width": 1280, "height": 800}, id="1280px"),
          pytest.param({"width": 390, "height": 844}, id="390px")]
FIGURES = ("fig-cone", "fig-hist", "fig-trends", "fig-confidence", "fig-classes",
           "fig-severity")

#: the boxes of one plotly figure's parts, in CSS pixels: [left, top, right, bottom] or null
_BOXES = """id => {
  const fig = document.getElementById(id);
  const box = e => { if (!e) return null; const b = e.getBoundingClientRect();
                     return [b.left, b.top, b.right, b.bottom]; };
  const bar = fig.querySelector('.modebar');
  return {svg: box(fig.querySelector('.main-svg')), title: box(fig.querySelector('.g-gtitle')),
          modebar: bar && getComputedStyle(bar).display !== 'none' ? box(bar) : null,
          legend: box(fig.querySelector('.legend')), xtitle: box(fig.querySelector('.g-xtitle')),
          texts: [...fig.querySelectorAll('.legendtext, .gtitle, .gtitle-subtitle')]
                 .map(e => [e.textContent, box(e)])};
}"""
_PX = 1.0  # rounding of sub-pixel boxes


def _overlap(a: list[float] | None, b: list[float] | None) -> bool:
    return (a is not None and b is not None and a[0] < b[2] - _PX and b[0] < a[2] - _PX
            and a[1] < b[3] - _PX and b[1] < a[3] - _PX)


def _inside(inner: list[float], outer: list[float]) -> bool:
    return (inner[0] >= outer[0] - _PX and inner[1] >= outer[1] - _PX
            and inner[2] <= outer[2] + _PX and inner[3] <= outer[3] + _PX)


@dataclass
class Units:
    failed_actuator: int
    due_actuator: int
    due_alarm: int
    due_tail: str


@pytest.fixture(scope="module")
def units(live: Live) -> Units:  # noqa: F811  (the imported fixture)
    """On the second aircraft WL1 failed at flight 71 (its last prediction at flight 40); on
    the third WL1 has flown 59 flights of a 60-flight life: its 5 % RUL quantile is 0.6."""
    failed = seed_results(live.factory, tail=live.tails[1])  # type: ignore[arg-type]
    with live.factory() as s:  # type: ignore[operator]
        station_faults.set_status(session=s, row=s.get(Injection, failed.injection_id),
                                                status="failed", failure_flight=71)
        s.commit()
    due = seed_results(live.factory, tail=live.tails[2], n_flights=59)  # type: ignore[arg-type]
    return Units(failed.actuator_id, due.actuator_id, due.alarm_id, live.tails[2])


def _page(browser: Any, live: Live, size: dict[str, int]) -> tuple[Any, Any, Console]:  # noqa: F811
    context = browser.new_context(viewport=size)
    page = context.new_page()
    console = Console(page)
    _sign_in(page, live.url, live.keys["admin"])
    return context, page, console


@pytest.mark.parametrize("size", WIDTHS)
def test_a_unit_due_now_reads_replace_now(live: Live, browser, units: Units,  # type: ignore[no-untyped-def]  # noqa: F811
                                          size: dict[str, int]) -> None:
    """Before: "act within 0 flights" (amber) for the last flight or so before a failure."""
    context, page, console = _page(browser, live, size)
    page.goto(f"{live.url}/actuators/{units.due_actuator}")
    urgency = page.locator("#urgency").inner_text()
    assert "replace now" in urgency and "due now" in urgency, urgency
    assert "due now" in page.locator("#rul-headline").inner_text()
    assert "within 0" not in page.locator("main").inner_text()

    page.goto(f"{live.url}/alarms")
    cell = page.locator(f"#alarm-{units.due_alarm} td.urgency")
    assert cell.inner_text().strip() == "replace now", cell.inner_text()
    assert "red" in (cell.locator(".pill").get_attribute("class") or "")
    assert "within 0" not in page.locator("main").inner_text()

    page.goto(f"{live.url}/fleet")
    row = page.locator("#fleet-grid tbody tr", has_text=units.due_tail)
    wl1 = row.locator('td[data-label="WL1"]')
    assert "replace now" in wl1.inner_text().lower(), wl1.inner_text()
    assert "≤ 0" not in row.inner_text()
    _shot(page, f"fleet-due-now-{size['width']}")
    assert console.errors == [], console.errors
    context.close()


@pytest.mark.parametrize("size", WIDTHS)
def test_charts_keep_titles_legends_and_axis_titles_apart(  # type: ignore[no-untyped-def]
        live: Live, browser, units: Units, size: dict[str, int]) -> None:  # noqa: F811
    """Before: at 1280 px the mode bar covered the failed unit's RUL histogram title; at
    390 px that title ran past the figure, the RUL cone's legend lay over its x axis title and
    the feature-trend legend was cut ("standby LVDT against the acti")."""
    context, page, console = _page(browser, live, size)
    page.goto(f"{live.url}/actuators/{units.failed_actuator}")
    for fig in FIGURES:
        page.wait_for_selector(f"#{fig} .main-svg", timeout=15_000)
    page.wait_for_timeout(300)  # responsive plots settle to the page's width
    _shot(page, f"actuator-failed-{size['width']}")
    problems = []
    for fig in FIGURES:
        b = page.evaluate(_BOXES, fig)
        if b["modebar"] is not None and _overlap(b["modebar"], b["title"]):
            problems.append(f"{fig}: the mode bar {b['modebar']} covers the title {b['title']}")
        if _overlap(b["legend"], b["xtitle"]):
            problems.append(f"{fig}: the legend {b['legend']} covers the x axis title "
                            f"{b['xtitle']}")
        if b["legend"] is not None and not _inside(b["legend"], b["svg"]):
            problems.append(f"{fig}: the legend {b['legend']} is cut by the figure {b['svg']}")
        for text, box in b["texts"]:
            if not _inside(box, b["svg"]):
                problems.append(f"{fig}: {text!r} {box} is cut by the figure {b['svg']}")
    assert problems == [], "\n".join(problems)
    title = page.evaluate("document.getElementById('fig-hist').layout.title")
    assert title["text"] == "Failed at flight 71: no life left", title
    assert title["subtitle"]["text"] == "last prediction, flight 40", title
    assert console.errors == [], console.errors
    context.close()


@pytest.mark.parametrize("size", WIDTHS)
def test_the_api_schema_sends_a_browser_without_a_key_to_sign_in(  # type: ignore[no-untyped-def]
        live: Live, browser, size: dict[str, int]) -> None:  # noqa: F811
    """Like /docs: /openapi.json in a browser without a key is the sign-in page, then the
    schema (before: a bare 401 error). A client that is no browser still gets 401."""
    context = browser.new_context(viewport=size)
    page = context.new_page()
    page.goto(f"{live.url}/openapi.json")
    assert page.url == f"{live.url}/signin?next=%2Fopenapi.json", page.url
    page.get_by_label("API key").fill(live.keys["viewer"])
    page.get_by_role("button", name="Sign in").click()
    page.wait_for_url(f"{live.url}/openapi.json")
    schema = json.loads(page.locator("body").inner_text())
    assert schema["info"]["title"].startswith("EMA") and "/api/v1/flights" in schema["paths"]
    context.close()
    tool = browser.new_context()
    bare = tool.request.get(f"{live.url}/openapi.json")
    assert bare.status == 401 and bare.headers["www-authenticate"] == "Bearer"
    tool.close()
