"""The dashboard in a real browser: Debian's /usr/bin/chromium driven by Playwright against
``hmsm serve`` on a free loopback port, fed by results written through ``seed_results``.

Flow: sign in; an alarm raised while the inbox is open arrives by server-sent events without a
reload; acknowledge it; the actuator page draws the RUL cone, the models page the confusion
matrix; an operator-capable user injects a fault and sees it listed; a viewer cannot inject.
No console errors anywhere. Screenshots at 1280x800 and 768 px go to ``test-artifacts/``.
"""

from __future__ import annotations

import re
import shutil
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import httpx
import pytest

from server.auth import create_key
from server.config import Settings
from server.db import make_engine, make_session_factory, session_scope
from server.migrate import ensure_schema
from tests.flightlog_factory import serials_for
from tests.live_server import running_server
from tests.web.seed import SeedResult, add_alarm, seed_results

CHROMIUM = "/usr/bin/chromium"
ARGS = ["--headless=new", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
        "--disable-background-networking", "--disable-component-update", "--disable-sync"]
ARTIFACTS = Path(__file__).resolve().parents[2] / "test-artifacts"

playwright_api = pytest.importorskip("playwright.sync_api", reason="playwright not installed")
NEEDS_CHROMIUM = pytest.mark.skipif(
    shutil.which(CHROMIUM) is None and not Path(CHROMIUM).exists(),
    reason=f"{CHROMIUM} is missing (apt-get install chromium); browser tests never download a "
    "browser")
pytestmark = [NEEDS_CHROMIUM, pytest.mark.slow]


@dataclass
class Live:
    url: str
    keys: dict[str, str]
    factory: object
    seed: SeedResult
    tails: list[str]


@pytest.fixture(scope="module")
def live(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Live]:
    data_dir = tmp_path_factory.mktemp("dashboard") / "data"
    settings = Settings(data_dir=data_dir)
    data_dir.mkdir(parents=True)
    engine = make_engine(settings.effective_database_url)
    ensure_schema(engine, settings.effective_database_url, auto_upgrade=True)
    factory = make_session_factory(engine)
    keys = {}
    with session_scope(factory) as session:
        for role in ("viewer", "maintainer", "operator", "admin"):
            keys[role] = create_key(session=session, name=f"browser-{role}", role=role)[1]
    with running_server({"HMSM_DATA_DIR": str(data_dir)}) as url:
        tails = ["B001", "B002", "B003"]
        for i, tail in enumerate(tails):
            r = httpx.post(f"{url}/api/v1/aircraft", headers={
                "Authorization": f"Bearer {keys['admin']}"}, json={
                "tail": tail, "base": ("Turin", "Naples")[i % 2], "actuators": serials_for(tail)})
            assert r.status_code == 201, r.text
        seed = seed_results(factory, tail=tails[0])
        yield Live(url=url, keys=keys, factory=factory, seed=seed, tails=tails)
    engine.dispose()


@pytest.fixture(scope="module")
def browser(live: Live) -> Iterator[object]:
    with playwright_api.sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=ARGS)
        yield b
        b.close()


class Console:
    """Console errors and uncaught page errors of one page."""

    def __init__(self, page) -> None:  # type: ignore[no-untyped-def]
        self.errors: list[str] = []
        page.on("console", lambda m: self.errors.append(f"console: {m.text}")
                if m.type == "error" else None)
        page.on("pageerror", lambda e: self.errors.append(f"pageerror: {e}"))


def _sign_in(page, url: str, key: str) -> None:  # type: ignore[no-untyped-def]
    page.goto(f"{url}/fleet")
    assert "/signin" in page.url
    page.get_by_label("API key").fill(key)
    page.get_by_role("button", name="Sign in").click()
    page.wait_for_url(f"{url}/fleet")


def _shot(page, name: str) -> None:  # type: ignore[no-untyped-def]
    ARTIFACTS.mkdir(exist_ok=True)
    page.screenshot(path=str(ARTIFACTS / f"{name}.png"), full_page=False)


def _plot_points(page, div_id: str) -> list[int]:  # type: ignore[no-untyped-def]
    page.wait_for_selector(f"#{div_id} .main-svg", timeout=15_000)
    return page.evaluate(
        "id => (document.getElementById(id).data || []).map(t => (t.x || t.z || []).length)",
        div_id)


def test_admin_flow_live_alarm_acknowledge_figures_inject(live: Live, browser) -> None:  # type: ignore[no-untyped-def]
    context = browser.new_context(viewport={"width": 1280, "height": 800})
    page = context.new_page()
    console = Console(page)
    url = live.url
    _sign_in(page, url, live.keys["admin"])
    assert page.locator("#fleet-grid tbody tr").count() == 3
    _shot(page, "fleet-1280")

    # an alarm raised while the inbox is open arrives through SSE, without a reload
    page.goto(f"{url}/alarms")
    # a locator wait, not wait_for_function: the page's CSP forbids eval of predicates
    page.locator("#live-status", has_text=re.compile(r"^live")).wait_for(timeout=10_000)
    page.evaluate("window.__noReload = 'still here'")
    new_id = add_alarm(live.factory, tail=live.tails[1], position="WT")  # type: ignore[arg-type]
    row = page.locator(f"#alarm-{new_id}")
    row.wait_for(timeout=10_000)
    assert page.evaluate("window.__noReload") == "still here"
    assert "open" in row.inner_text()
    _shot(page, "alarms-1280")

    # acknowledge it with a note (keyboard: type in the labelled field, press the button)
    page.get_by_label(f"Note for alarm {new_id}").fill("checked on ground")
    row.get_by_role("button", name="Acknowledge").click()
    page.wait_for_url(f"{url}/alarms")
    row = page.locator(f"#alarm-{new_id}")
    assert "acknowledged" in row.inner_text() and "checked on ground" in row.inner_text()

    # the actuator page draws the RUL cone (median + band + truth cone) with data
    page.goto(f"{url}/actuators/{live.seed.actuator_id}")
    points = _plot_points(page, "fig-cone")
    assert len(points) == 4 and min(points) > 5, points
    names = page.evaluate("document.getElementById('fig-cone').data.map(t => t.name)")
    assert "median RUL" in names and "true RUL ±20 %" in names
    for fig in ("fig-hist", "fig-trends", "fig-confidence", "fig-classes", "fig-severity"):
        assert max(_plot_points(page, fig)) > 0, fig
    _shot(page, "actuator-1280")
    page.set_viewport_size({"width": 768, "height": 1024})
    page.wait_for_timeout(300)
    _shot(page, "actuator-768")
    width = page.evaluate("document.documentElement.scrollWidth")
    assert width <= 768, f"horizontal scroll at tablet width: {width}px"
    page.set_viewport_size({"width": 1280, "height": 800})

    # the models page draws the confusion matrix
    page.goto(f"{url}/models")
    assert _plot_points(page, "fig-confusion") == [7]
    assert page.locator("#per-class tbody tr").count() == 7
    _shot(page, "models-1280")

    # inject a fault from the test station and see it listed
    page.goto(f"{url}/test-station")
    form = page.locator("#inject-form")
    form.get_by_label("Aircraft").select_option(live.tails[2])
    form.get_by_label("Position").select_option("WL2")
    form.get_by_label("Fault mode").select_option("MTWEAR")
    form.get_by_label("Onset flight").fill("5")
    form.get_by_label("Time to failure [flights]").fill("200")
    page.get_by_role("button", name="Inject fault").click()
    page.wait_for_url(f"{url}/test-station")
    listed = page.locator("#injection-table tbody tr", has_text=live.tails[2])
    assert listed.count() == 1 and "MTWEAR" in listed.inner_text()
    _shot(page, "test-station-1280")

    # the fleet page at tablet width, and keyboard focus is visible
    page.set_viewport_size({"width": 768, "height": 1024})
    page.goto(f"{url}/fleet")
    page.keyboard.press("Tab")
    assert page.evaluate("document.activeElement.className") == "skip"
    _shot(page, "fleet-768")
    page.goto(f"{url}/evaluation")
    assert page.locator("#not-run").count() == 1

    assert console.errors == [], console.errors
    context.close()


def test_viewer_cannot_inject(live: Live, browser) -> None:  # type: ignore[no-untyped-def]
    context = browser.new_context(viewport={"width": 1280, "height": 800})
    page = context.new_page()
    console = Console(page)
    _sign_in(page, live.url, live.keys["viewer"])
    page.goto(f"{live.url}/test-station")
    assert page.locator("#inject-form").count() == 0
    assert page.locator("#no-inject").is_visible()
    page.goto(f"{live.url}/alarms")
    assert page.get_by_role("button", name="Acknowledge").count() == 0
    # the server refuses the post even if the form is forged (same cookie, same origin)
    r = context.request.post(f"{live.url}/test-station/injections", form={
        "aircraft": live.tails[1], "position": "WT", "fault_mode": "SE", "csrf": "x"})
    assert r.status == 403
    r = context.request.post(f"{live.url}/api/v1/test-station/injections", data={
        "aircraft": live.tails[1], "position": "WT", "fault_mode": "SE"})
    assert r.status == 403
    assert console.errors == [], console.errors
    context.close()


def test_replacement_with_a_work_order_from_the_actuator_page(live: Live, browser) -> None:  # type: ignore[no-untyped-def]
    """A maintenance engineer replaces a unit in alarm (BDO: replace now) from its page with a
    work-order number; the page of the new unit shows it healthy, the trail shows who, when,
    the order."""
    tail = live.tails[2]
    add_alarm(live.factory, tail=tail, position="WT", fault_mode="BDO", rul=None)  # type: ignore[arg-type]
    context = browser.new_context(viewport={"width": 1280, "height": 800})
    page = context.new_page()
    console = Console(page)
    _sign_in(page, live.url, live.keys["maintainer"])
    cell = page.locator("#fleet-grid tbody tr", has_text=tail).locator("td.cell").nth(2)
    assert "red" in (cell.get_attribute("class") or "")
    assert "replace now" in cell.inner_text().lower()  # the badge is set in capitals
    cell.locator("a").click()
    page.wait_for_url(re.compile(r"/actuators/\d+$"))
    old_url = page.url
    assert "replace now" in page.locator("#urgency").inner_text().lower()
    assert page.locator("#in-alarm").inner_text().startswith("yes")

    form = page.locator("#replace-form")
    form.get_by_label("New serial").fill("WT-BROWSER-1")
    form.get_by_label("Work order").fill("WO-2026-0777")
    form.get_by_label("Note").fill("open MOSFET leg confirmed")
    form.get_by_role("button", name="Replace actuator").click()
    page.wait_for_url(lambda u: u != old_url and "/actuators/" in u)
    assert "WT-BROWSER-1" in page.locator("h1").inner_text()
    assert "healthy" in page.locator("#urgency").inner_text().lower()
    assert page.locator("#in-alarm").inner_text() == "no"
    assert page.locator("#flights-seen").inner_text() == "0"
    trail = page.locator("#maintenance-trail tbody tr").first
    text = trail.inner_text()
    assert "replaced" in text and "WO-2026-0777" in text and "browser-maintainer" in text
    _shot(page, "actuator-replaced-1280")

    page.goto(old_url)  # the removed unit says so, and is no longer "in alarm"
    assert page.locator("#removed-notice").is_visible()
    assert page.locator("#in-alarm").inner_text() == "removed"
    assert page.locator("#replace-form").count() == 0
    page.goto(f"{live.url}/fleet")
    cell = page.locator("#fleet-grid tbody tr", has_text=tail).locator("td.cell").nth(2)
    assert "green" in (cell.get_attribute("class") or "")
    assert console.errors == [], console.errors
    context.close()


PHONE = {"width": 390, "height": 844}


def test_every_page_fits_a_phone_screen(live: Live, browser) -> None:  # type: ignore[no-untyped-def]
    """At 390 px no page is wider than the screen: the fleet grid and the alarm inbox become
    one card per row with every column labelled (WT and Min RUL included, the inbox's action
    in reach); other tables scroll inside their own box."""
    context = browser.new_context(viewport=PHONE)
    page = context.new_page()
    console = Console(page)
    url = live.url
    _sign_in(page, url, live.keys["admin"])
    pages = {"fleet": "/fleet", "alarms": "/alarms",
             "actuator": f"/actuators/{live.seed.actuator_id}", "models": "/models",
             "test-station": "/test-station", "evaluation": "/evaluation"}
    for name, path in pages.items():
        page.goto(url + path)
        if name == "actuator":
            page.wait_for_selector("#fig-cone .main-svg", timeout=15_000)
        width = page.evaluate("document.documentElement.scrollWidth")
        assert width <= PHONE["width"], f"{path}: {width} px wide at 390 px"
        _shot(page, f"{name}-390")

    page.goto(f"{url}/fleet")
    assert page.locator("#fleet-cards-hint").is_visible()
    card = page.locator("#fleet-grid tbody tr").first
    for label in ("WL1", "WL2", "WT", "Min RUL"):
        cell = card.locator(f'td[data-label="{label}"]')
        box = cell.bounding_box()
        assert cell.is_visible() and box is not None and box["x"] + box["width"] <= 390, label
    page.goto(f"{url}/alarms")
    button = page.get_by_role("button", name="Acknowledge").first
    box = button.bounding_box()
    assert box is not None and box["x"] >= 0 and box["x"] + box["width"] <= 390, box
    assert console.errors == [], console.errors
    context.close()


def test_test_station_injections_read_on_a_phone(live: Live, browser) -> None:  # type: ignore[no-untyped-def]
    """At 390x844 the injections are cards, two short fields a line: nothing scrolls sideways,
    not even inside the table's box, the status is on the screen and the cancel button in the
    viewport once its row is scrolled into view, and it cancels (before: the table scrolled
    450 px in its box, status and cancel off-screen, rows about 300 px tall). The charts on a
    phone have no mode bar over their titles."""
    for tail in live.tails:  # the first whose WL2 has no live MTWEAR (one per mode of a unit)
        r = httpx.post(f"{live.url}/api/v1/test-station/injections",
                       headers={"Authorization": f"Bearer {live.keys['operator']}"},
                       json={"aircraft": tail, "position": "WL2", "fault_mode": "MTWEAR",
                             "onset_flight": 40, "time_to_failure_flights": 120}, timeout=30)
        if r.status_code != 409:
            break
    assert r.status_code == 201, r.text
    injection = r.json()["id"]
    context = browser.new_context(viewport=PHONE)
    page = context.new_page()
    console = Console(page)
    _sign_in(page, live.url, live.keys["admin"])
    page.goto(f"{live.url}/test-station")
    overflow = page.evaluate("""() => [document.documentElement,
        document.querySelector('#injection-table').parentElement]
        .map(e => e.scrollWidth - e.clientWidth)""")
    assert overflow == [0, 0], overflow  # page, table box
    row = page.locator(f"#injection-{injection}")
    row.scroll_into_view_if_needed()
    _shot(page, "test-station-390")
    height = row.bounding_box()["height"]
    assert height < PHONE["height"] / 3, height  # seven lines: about 260 px
    for cell in (row.locator('td[data-label="Status"]'), row.get_by_role("button")):
        box = cell.bounding_box()
        assert box is not None and box["x"] >= 0 and box["x"] + box["width"] <= PHONE["width"]
    button = row.get_by_role("button", name=re.compile("^Cancel injection"))
    button.scroll_into_view_if_needed()
    assert button.is_visible() and _in_viewport(page, button)
    button.click()  # and it works: the aircraft is free again for the other tests
    page.wait_for_url(f"{live.url}/test-station")
    assert "cancelled" in page.locator(f"#injection-{injection}").inner_text()

    page.goto(f"{live.url}/actuators/{live.seed.actuator_id}")
    page.wait_for_selector("#fig-cone .main-svg", timeout=15_000)
    assert page.locator(".modebar").count() == 0
    assert console.errors == [], console.errors
    context.close()


def _in_viewport(page, locator) -> bool:  # type: ignore[no-untyped-def]
    box = locator.bounding_box()
    size = page.viewport_size
    return (box is not None and box["x"] >= 0 and box["y"] >= 0
            and box["x"] + box["width"] <= size["width"]
            and box["y"] + box["height"] <= size["height"])


def test_a_pair_alarm_and_a_cancelled_injection_in_the_browser(live: Live, browser) -> None:  # type: ignore[no-untyped-def]
    """An admin acknowledges a winglet-pair alarm (one row, both drives) with one click; an
    operator cancels a live injection from its row; no probability reads as certain."""
    tail = live.tails[1]
    wl1 = add_alarm(live.factory, tail=tail, position="WL1", fault_mode="REWEAR",  # type: ignore[arg-type]
                    confidence=0.999999)
    wl2 = add_alarm(live.factory, tail=tail, position="WL2", fault_mode="REWEAR")  # type: ignore[arg-type]
    context = browser.new_context(viewport={"width": 1280, "height": 800})
    page = context.new_page()
    console = Console(page)
    _sign_in(page, live.url, live.keys["admin"])
    page.goto(f"{live.url}/alarms?status=open")
    row = page.locator("tr.pair", has_text=tail)
    assert row.count() == 1 and "WL1 or WL2" in row.inner_text()
    assert "100.0 %" not in page.locator("#alarm-table").inner_text()
    row.get_by_role("button", name="Acknowledge").click()
    page.wait_for_url(f"{live.url}/alarms?status=open")
    assert page.locator(f"#alarm-{wl1}, #alarm-{wl2}").count() == 0  # both left "open"

    page.goto(f"{live.url}/test-station")
    form = page.locator("#inject-form")
    form.get_by_label("Aircraft").select_option(live.tails[1])
    form.get_by_label("Position").select_option("WT")
    form.get_by_label("Fault mode").select_option("MTEL")
    form.get_by_label("Time to failure [flights]").fill("60")
    page.get_by_role("button", name="Inject fault").click()
    page.wait_for_url(f"{live.url}/test-station")
    listed = page.locator("#injection-table tbody tr", has_text=live.tails[1]).first
    listed.get_by_role("button", name=re.compile("^Cancel injection")).click()
    page.wait_for_url(f"{live.url}/test-station")
    listed = page.locator("#injection-table tbody tr", has_text=live.tails[1]).first
    assert "cancelled" in listed.inner_text()
    assert console.errors == [], console.errors
    context.close()
