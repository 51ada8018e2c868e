"""What the pages claim holds: no probability shown as certain, one alarm for a winglet pair
the evidence cannot split, a 95 % lower bound as the RUL headline, a live injection's planned
RUL on the cone, and the test station's cancel button and span warning."""

from __future__ import annotations

import json

import pytest
from sqlalchemy import select

from server.db import session_scope
from server.models import Alarm, GroundTruth, Injection
from server.web.routes import csrf_token, templates
from tests.web.seed import add_alarm, seed_results
from tests.web.test_pages import sign_in


def _figure(html: str, target: str) -> dict:
    start = html.index(f'data-target="{target}">') + len(f'data-target="{target}">')
    return json.loads(html[start:html.index("</script>", start)])


def test_a_probability_is_never_shown_as_certain(app, client, keys, aircraft) -> None:
    alarm = add_alarm(app.state.session_factory, tail=aircraft, position="WT",
                      fault_mode="BDO", confidence=0.999999)
    with session_scope(app.state.session_factory) as s:
        s.get(Alarm, alarm).class_probability = 0.99996
    sign_in(client, keys["viewer"])
    row = client.get("/alarms").text.split(f'id="alarm-{alarm}"')[1].split("</tr>")[0]
    assert "100.0 %" not in row and row.count("&gt;99 %") == 2, row  # class p and confidence


def test_a_winglet_pair_alarm_is_one_row_naming_both_drives(app, client, keys, aircraft
                                                            ) -> None:
    factory = app.state.session_factory
    wl1 = add_alarm(factory, tail=aircraft, position="WL1", fault_mode="REWEAR", rul=40.0)
    wl2 = add_alarm(factory, tail=aircraft, position="WL2", fault_mode="REWEAR", rul=40.0)
    other = add_alarm(factory, tail=aircraft, position="WT", fault_mode="TTS")
    sign_in(client, keys["admin"])
    page = client.get("/alarms").text
    rows = [r for r in page.split('<tr id="alarm-')[1:]]
    assert len(rows) == 2  # the pair is one row, the wingtip alarm another
    # the count is of the rows shown, not of the alarms behind them (was "3 of 3")
    assert 'id="alarm-count">2 of 2 alarms (a winglet pair' in page
    pair = next(r for r in rows if "winglet pair" in r)
    assert "WL1</a> or <a" in pair and ">WL2</a>" in pair
    assert "the evidence does not tell which drive" in pair
    lead, partner = (wl1, wl2) if pair.startswith(f"{wl1}\"") else (wl2, wl1)
    assert f'name="partner" value="{partner}"' in pair

    # the actuator page of either drive names its partner
    with session_scope(factory) as s:
        wl2_actuator = s.get(Alarm, wl2).actuator_id
    notice = client.get(f"/actuators/{wl2_actuator}").text
    assert 'id="pair-notice"' in notice and "WL1 has the same" in notice

    # one acknowledgement acts on both alarms of the pair, and on them only
    r = client.post(f"/alarms/{lead}/acknowledge", data={
        "note": "inspect both rod ends", "csrf": csrf_token(keys["admin"]),
        "partner": str(partner)})
    assert r.status_code == 200, r.text
    with session_scope(factory) as s:
        status = {a.id: a.status for a in s.scalars(select(Alarm))}
    assert status == {wl1: "acknowledged", wl2: "acknowledged", other: "open"}
    # a partner id that is not the pair partner is ignored
    r = client.post(f"/alarms/{lead}/close", data={"csrf": csrf_token(keys["admin"]),
                                                   "partner": str(other)})
    with session_scope(factory) as s:
        status = {a.id: a.status for a in s.scalars(select(Alarm))}
    assert status == {lead: "closed", partner: "acknowledged", other: "open"}


def test_a_different_mode_on_the_partner_is_a_separate_alarm(app, client, keys, aircraft
                                                             ) -> None:
    factory = app.state.session_factory
    add_alarm(factory, tail=aircraft, position="WL1", fault_mode="REWEAR")
    add_alarm(factory, tail=aircraft, position="WL2", fault_mode="TTS")
    sign_in(client, keys["viewer"])
    page = client.get("/alarms").text
    assert page.count('<tr id="alarm-') == 2 and "winglet pair:" not in page


def test_the_rul_headline_is_a_95pct_lower_bound_beside_the_median(app, client, keys,
                                                                   aircraft) -> None:
    seeded = seed_results(app.state.session_factory, tail=aircraft)
    sign_in(client, keys["viewer"])
    html = client.get(f"/actuators/{seeded.actuator_id}").text
    cone = _figure(html, "fig-cone")
    median = next(t for t in cone["data"] if t["name"] == "median RUL")["y"][-1]
    headline = html[html.index('id="rul-at-least"'):].split("</strong>")[0]
    low = 0.6 * median  # the seeded distribution's 5 % quantile
    assert f"at least {low:.0f} flights (95 %)" in headline, headline
    assert f'id="median-rul">{median:.0f} flights' in html


def test_a_live_injection_shows_its_planned_rul_until_failure(app, client, keys, aircraft
                                                              ) -> None:
    factory = app.state.session_factory
    seeded = seed_results(factory, tail=aircraft, onset=15, life=60)
    with session_scope(factory) as s:  # live: the true RUL is not known yet, the plan is
        s.get(Injection, seeded.injection_id).planned_failure_flight = 62
        for gt in s.scalars(select(GroundTruth)):
            gt.true_rul_flights = None
    sign_in(client, keys["viewer"])
    html = client.get(f"/actuators/{seeded.actuator_id}").text
    assert 'id="truth-hint"' in html and "planned RUL" in html
    planned = next(t for t in _figure(html, "fig-cone")["data"]
                   if t["name"] == "planned RUL (test station)")
    assert planned["y"][-1] == 62 - planned["x"][-1]
    station = client.get("/test-station").text
    assert f'id="plan-{seeded.injection_id}">planned failure at flight 62' in station

    with session_scope(factory) as s:  # failed: the true RUL replaces the plan
        inj = s.get(Injection, seeded.injection_id)
        inj.status, inj.failure_flight = "failed", 61
        for gt in s.scalars(select(GroundTruth)):
            gt.true_rul_flights = 61 - gt.flight_number
    html = client.get(f"/actuators/{seeded.actuator_id}").text
    names = {t["name"] for t in _figure(html, "fig-cone")["data"]}
    assert "true RUL" in names and "planned RUL (test station)" not in names


def test_an_operator_cancels_an_injection_from_the_page(client, keys, aircraft) -> None:
    sign_in(client, keys["operator"])
    token = csrf_token(keys["operator"])
    client.post("/test-station/injections", data={
        "csrf": token, "aircraft": aircraft, "position": "WT", "fault_mode": "MTEL",
        "time_to_failure_flights": "120"})
    page = client.get("/test-station").text
    assert 'id="cancel-1"' in page
    r = client.post("/test-station/injections/1/cancel", data={"csrf": token})
    assert r.status_code == 200 and 'id="cancel-1"' not in r.text
    with session_scope(client.app.state.session_factory) as s:
        assert s.get(Injection, 1).status == "cancelled"
    again = client.post("/test-station/injections/1/cancel", data={"csrf": token})
    assert again.status_code == 409 and "only pending or active" in again.text
    sign_in(client, keys["viewer"])
    assert 'id="cancel-' not in client.get("/test-station").text
    assert client.post("/test-station/injections/1/cancel",
                       data={"csrf": csrf_token(keys["viewer"])}).status_code == 403


def test_the_station_page_warns_of_a_span_outside_the_models_training(
        client, keys, aircraft, active_model, shipped_model) -> None:  # type: ignore[no-untyped-def]
    low, high = shipped_model[1]["campaign"]["spans_flights"]["TTS"]
    sign_in(client, keys["operator"])
    client.post("/test-station/injections", data={
        "csrf": csrf_token(keys["operator"]), "aircraft": aircraft, "position": "WT",
        "fault_mode": "TTS", "time_to_failure_flights": str(high * 2)})
    page = client.get("/test-station").text
    warning = page[page.index('id="span-warning-1"'):].split("</small>")[0]
    assert f"{low}-{high} flights" in warning and "extrapolation" in warning



@pytest.mark.parametrize(("value", "text"), [(1.2, "1 flight"), (0.6, "1 flight"),
                                             (1.6, "2 flights"), (40.0, "40 flights")])
def test_a_count_of_flights_takes_its_plural_as_displayed(value: float,
                                                          text: str) -> None:
    macro = templates().env.get_template("_macros.html").module.flights  # type: ignore[attr-defined]
    assert str(macro(value)) == text
