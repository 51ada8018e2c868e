"""What the pages show once the facts have moved on (the issue filed after trying the demo):
a failed unit shows no life left and names the failed drive of the winglet pair; after a
no-fault-found the unit shows no fault mode, RUL or cone, the alarm its class at raising and
the later change of its leading class; the inbox counts its rows; the confidence chart draws
the model's own alarm level; no source path on the actuator page.

Debian's /usr/bin/chromium driven by Playwright against ``hmsm serve``, with the fixtures of
``test_dashboard.py`` (a server of this module's own)."""

from __future__ import annotations

import re

from server.models import Injection
from server.services import station_faults
from tests.browser.test_dashboard import (  # noqa: F401  (fixtures of this module's own)
    Console,
    Live,
    _plot_points,
    _sign_in,
    browser,
    live,
    pytestmark,
)
from tests.web.seed import add_alarm, seed_class_change, seed_results


def test_a_failed_unit_shows_no_life_and_the_pair_row_names_it(live: Live, browser) -> None:  # type: ignore[no-untyped-def]  # noqa: F811
    """Issues 7, 8, 12: WL1 failed at flight 71 while WL2 alarms in the same mode."""
    tail = live.tails[1]
    seed = seed_results(live.factory, tail=tail, position="WL1")  # type: ignore[arg-type]
    add_alarm(live.factory, tail=tail, position="WL2", fault_mode="DMD", rul=40.0)  # type: ignore[arg-type]
    with live.factory() as s:  # type: ignore[operator]
        station_faults.set_status(session=s, row=s.get(Injection, seed.injection_id),
                                                status="failed", failure_flight=71)
        s.commit()
    context = browser.new_context(viewport={"width": 1280, "height": 800})
    page = context.new_page()
    console = Console(page)
    _sign_in(page, live.url, live.keys["admin"])

    page.goto(f"{live.url}/actuators/{seed.actuator_id}")
    headline = page.locator("#rul-headline").inner_text()
    assert "failed" in headline and "at least" not in headline, headline
    assert page.locator("#median-rul").inner_text() == "0 flights (failed)"
    assert page.locator(f"#own-alarm-{seed.alarm_id}").inner_text().count("0 (failed)") == 1
    notice = page.locator("#pair-notice").inner_text()
    assert "WL1 (this drive) failed at flight 71" in notice, notice
    assert "does not tell" not in notice
    assert "server/services/urgency.py" not in page.locator("main").inner_text()

    page.goto(f"{live.url}/alarms")
    row = page.locator("tr.pair", has_text=tail)
    assert row.count() == 1
    text = row.inner_text()
    assert "WL1 failed at flight 71" in text and "does not tell" not in text, text
    assert row.locator('td[data-label="Median RUL"]').inner_text() == "0 (failed)"
    assert "replace now" in row.locator("td.urgency").inner_text().lower()
    # the count is of the rows shown (the pair is one)
    rows = page.locator("#alarm-table tbody tr.alarm").count()
    count = page.locator("#alarm-count").inner_text()
    assert count.startswith(f"{rows} of {rows} alarms"), (count, rows)
    assert console.errors == [], console.errors
    context.close()


def test_no_fault_found_leaves_no_stale_fault_and_keeps_the_class_at_raising(  # type: ignore[no-untyped-def]
        live: Live, browser) -> None:  # noqa: F811  (the imported fixtures)
    """Issues 9, 10, 12: an alarm raised as MTEL, its leading class DMD since flight 25, closed
    as no fault found from the actuator page; the model's alarm confidence is 0.95."""
    tail = live.tails[2]
    seed = seed_results(live.factory, tail=tail, position="WL1")  # type: ignore[arg-type]
    seed_class_change(live.factory, seed, tail=tail)  # type: ignore[arg-type]
    context = browser.new_context(viewport={"width": 1280, "height": 800})
    page = context.new_page()
    console = Console(page)
    _sign_in(page, live.url, live.keys["maintainer"])

    url = f"{live.url}/actuators/{seed.actuator_id}"
    page.goto(url)
    _plot_points(page, "fig-confidence")
    level = page.evaluate("document.getElementById('fig-confidence').data"
                          ".filter(t => t.name.startsWith('alarm level')).map(t => t.y[0])")
    assert level == [0.95], level
    assert "server/services/urgency.py" not in page.locator("main").inner_text()
    own = page.locator(f"#own-alarm-{seed.alarm_id}").inner_text()
    assert "DMD" in own and "raised as MTEL" in own, own
    change = page.locator("#alarm-events tbody tr").first.inner_text()
    assert "MTEL" in change and "DMD" in change and "25" in change, change
    assert page.locator("#fault-mode").inner_text().startswith("DMD")
    assert "at least" in page.locator("#rul-headline").inner_text()

    form = page.locator("#inspect-form")
    form.get_by_label("Work order").fill("WO-2026-0901")
    form.get_by_label("Finding").fill("rod end within limits")
    form.get_by_role("button", name="Close as false alarm").click()
    page.wait_for_url(url)
    assert "healthy" in page.locator("#urgency").inner_text().lower()
    assert page.locator("#in-alarm").inner_text() == "no"
    assert page.locator("#fault-mode").inner_text() == "–"
    assert page.locator("#rul-headline").inner_text() == "–"
    assert page.locator("#median-rul").inner_text() == "–"
    assert "no fault found" in page.locator("#no-prognosis").inner_text()
    page.wait_for_selector("#fig-cone .main-svg", timeout=15_000)
    assert max(_plot_points(page, "fig-cone") or [0]) == 0  # no cone: "no data yet"
    assert "no data yet" in (page.locator("#fig-cone").text_content() or "")
    own = page.locator(f"#own-alarm-{seed.alarm_id}").inner_text()
    assert "no fault found" in own and "raised as MTEL" in own, own
    trail = page.locator("#maintenance-trail tbody tr").first.inner_text()
    assert "WO-2026-0901" in trail and "raised as MTEL" in trail, trail

    page.goto(f"{live.url}/alarms?status=closed")
    closed = page.locator(f"#alarm-{seed.alarm_id}").inner_text()
    assert re.search(r"raised as\s+MTEL", closed), closed
    assert console.errors == [], console.errors
    context.close()
