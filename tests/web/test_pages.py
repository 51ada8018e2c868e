"""Dashboard pages through the TestClient: sign-in cookie, access per role, CSRF, form posts,
the live-event stream, and the fleet page at 100 aircraft x 3 actuators."""

from __future__ import annotations

import json
import logging
import time

import pytest
from fastapi.testclient import TestClient
from sqlalchemy import event, select

from server.db import session_scope
from server.models import (
    Actuator,
    ActuatorState,
    Aircraft,
    Alarm,
    Flight,
    Injection,
    Prognosis,
)
from server.web.routes import csrf_token
from tests.signin import sign_in as sign_in_form
from tests.web.seed import add_alarm, seed_results

log = logging.getLogger(__name__)

PAGES = ["/fleet", "/alarms", "/models", "/test-station", "/evaluation"]


def sign_in(client: TestClient, key: str) -> None:
    r = sign_in_form(client, key)
    assert r.status_code == 303, r.text
    assert r.headers["location"] == "/fleet"


@pytest.fixture
def seeded(app, aircraft):  # type: ignore[no-untyped-def]
    return seed_results(app.state.session_factory, tail=aircraft)


def test_signin_sets_httponly_samesite_cookie_and_signout_clears_it(client, keys) -> None:
    r = sign_in_form(client, keys["viewer"], next="/alarms")
    assert r.status_code == 303 and r.headers["location"] == "/alarms"
    cookie = r.headers["set-cookie"]
    assert cookie.startswith("hmsm_session=")
    lowered = cookie.lower()
    assert "httponly" in lowered and "samesite=strict" in lowered and "path=/" in lowered
    assert "secure" not in lowered  # plain http in the test client
    r = client.post("/signout", data={"csrf": csrf_token(keys["viewer"])},
                    follow_redirects=False)
    assert r.status_code == 303 and 'hmsm_session=""' in r.headers["set-cookie"]


def test_signin_rejects_unknown_key_and_foreign_next(client, keys) -> None:
    r = sign_in_form(client, "hmsm_nope")
    assert r.status_code == 401 and "unknown or revoked" in r.text
    assert "set-cookie" not in r.headers
    r = sign_in_form(client, keys["viewer"], next="//evil.example/x")
    assert r.headers["location"] == "/fleet"


def test_root_redirects_to_fleet(client) -> None:
    r = client.get("/", follow_redirects=False)
    assert r.status_code in (302, 303, 307) and r.headers["location"] == "/fleet"


@pytest.mark.parametrize("path", PAGES + ["/actuators/1"])
def test_pages_redirect_to_signin_without_cookie(client, aircraft, path: str) -> None:
    r = client.get(path, follow_redirects=False)
    assert r.status_code == 303
    assert r.headers["location"].startswith("/signin?next=")


def test_every_page_renders_for_a_viewer_without_admin_controls(client, keys, seeded) -> None:
    sign_in(client, keys["viewer"])
    for path in PAGES + [f"/actuators/{seeded.actuator_id}"]:
        r = client.get(path)
        assert r.status_code == 200, (path, r.text[:500])
        assert r.headers["content-type"].startswith("text/html")
        assert "script-src 'self'" in r.headers["content-security-policy"]
        assert "<script>" not in r.text  # no inline script (CSP)
        # a viewer gets no forms that change anything: only sign-out's carries the token
        assert r.text.count('name="csrf"') == 1 and 'action="/signout"' in r.text
    alarms = client.get("/alarms").text
    assert f'id="alarm-{seeded.alarm_id}"' in alarms and ">Acknowledge</button>" not in alarms
    station = client.get("/test-station").text
    assert 'id="inject-form"' not in station and 'id="no-inject"' in station


def test_modes_and_features_carry_their_plain_names(client, keys, seeded) -> None:
    sign_in(client, keys["viewer"])
    dmd = '<abbr title="magnet degradation">DMD</abbr> <span class="mode-name">magnet degradation'
    assert dmd in client.get("/alarms").text
    page = client.get(f"/actuators/{seeded.actuator_id}").text
    assert page.count(dmd) >= 2  # the header's fault mode and the alarm list
    assert "magnet flux deficit" in page  # the feature-trend legend
    fleet = client.get("/fleet").text
    assert '<abbr title="magnet degradation">DMD</abbr>' in fleet
    assert "DMD (magnet degradation)" in fleet  # the cell's accessible label
    assert '<abbr title="magnet degradation">DMD</abbr>' in client.get("/test-station").text
    sign_in(client, keys["operator"])  # the injection form
    assert "TTS: turn-to-turn short in the motor windings" in client.get("/test-station").text


def test_the_header_names_the_open_alarms_mode_even_without_a_prognosis(
        app, client, keys, seeded, aircraft) -> None:  # type: ignore[no-untyped-def]
    """An abrupt fault (BDO) gets no prognosis: the header follows the alarm, as the fleet
    grid does."""
    add_alarm(app.state.session_factory, tail=aircraft, position="WT", fault_mode="BDO")
    sign_in(client, keys["viewer"])
    wt = next(c for c in client.get("/api/v1/fleet/health",
                                    headers={"Authorization": f"Bearer {keys['viewer']}"}
                                    ).json() if c["position"] == "WT")
    assert wt["fault_mode"] == "BDO"
    page = client.get(f"/actuators/{wt['actuator_id']}").text
    header = page[page.index('id="fault-mode"'):page.index("</dd>", page.index('id="fault-mode"'))]
    assert ">BDO</abbr>" in header
    assert 'id="median-rul">–</dd>' in page  # no RUL: a dash, not "- flights"


def test_two_modes_on_one_unit_show_with_their_probabilities_and_rul(
        app, client, keys, seeded, aircraft) -> None:  # type: ignore[no-untyped-def]
    """An alarm whose unit carries two modes lists both, the leading one first, each with its
    own probability and median RUL (one named by its own feature says so), a mode not yet
    confirmed marked provisional, in the inbox,
    on the actuator page and in the API; an alarm with one mode lists none."""
    factory = app.state.session_factory
    both = [{"mode": "TTS", "probability": 0.97, "rul_median_flights": 120.0,
             "confirmed": True},  # stored before the flag
            {"mode": "DMD", "probability": 0.74, "rul_median_flights": 80.4,
             "confirmed": False, "by_feature": False},
            {"mode": "MTEL", "probability": 0.08, "rul_median_flights": 300.0,
             "confirmed": False, "by_feature": True}]
    two = add_alarm(factory, tail=aircraft, position="WT", fault_mode="TTS", rul=80.4,
                    modes=both)
    one = add_alarm(factory, tail=aircraft, position="WL1", fault_mode="MTEL",
                    modes=[{"mode": "MTEL", "probability": 0.9, "rul_median_flights": 50.0}])
    sign_in(client, keys["viewer"])
    inbox = client.get("/alarms").text
    text = ('modes present: TTS 0.97 (RUL 120) · DMD 0.74 (RUL 80) '
            '<span class="provisional">provisional</span> · MTEL <span class="by-feature"')
    assert text in inbox[inbox.index(f'id="alarm-{two}"'):].split("</tr>")[0]
    assert "modes present" not in inbox[inbox.index(f'id="alarm-{one}"'):].split("</tr>")[0]
    items = client.get("/api/v1/alarms", headers={
        "Authorization": f"Bearer {keys['viewer']}"}).json()["items"]
    # a mode stored without the flag (an alarm before it) reads as named by its probability
    assert {a["id"]: a["modes"] for a in items}[two] == [
        {"by_feature": False, **m} for m in both]
    act = next(a["actuator_id"] for a in items if a["id"] == two)
    assert text in client.get(f"/actuators/{act}").text


def test_an_ambiguity_group_names_both_drives_with_their_probabilities(
        app, client, keys, seeded, aircraft) -> None:  # type: ignore[no-untyped-def]
    """A winglet drive's alarm on a feature its partner moves too names both drives, the
    likelier first, in the inbox, on the actuator page and in the API; a unit's own alarm
    shows no group."""
    factory = app.state.session_factory
    own = add_alarm(factory, tail=aircraft, position="WT", fault_mode="DMD",
                    isolation={"WT": 1.0})
    pair = add_alarm(factory, tail=aircraft, position="WL2", fault_mode="MTEL",
                     isolation={"WL1": 0.27, "WL2": 0.73})
    sign_in(client, keys["viewer"])
    inbox = client.get("/alarms").text
    row = inbox[inbox.index(f'id="alarm-{pair}"'):]
    assert "ambiguity group: WL2 0.73 · WL1 0.27" in row[:row.index("</tr>")]
    assert "ambiguity group" not in inbox[inbox.index(f'id="alarm-{own}"'):].split("</tr>")[0]
    items = client.get("/api/v1/alarms", headers={
        "Authorization": f"Bearer {keys['viewer']}"}).json()["items"]
    assert {a["id"]: a["isolation"] for a in items}[pair] == {"WL1": 0.27, "WL2": 0.73}
    act = next(a["actuator_id"] for a in items if a["id"] == pair)
    assert "ambiguity group: WL2 0.73 · WL1 0.27" in client.get(f"/actuators/{act}").text


def test_the_leading_rate_hypothesis_is_shown_beside_the_band(app, client, keys, seeded
                                                               ) -> None:  # type: ignore[no-untyped-def]
    """A prediction of a bank of rate hypotheses names the fault's speed and its weight on
    the actuator page and in the API; one without a bank shows no such line."""
    sign_in(client, keys["viewer"])
    assert 'id="rul-hypothesis"' not in client.get(f"/actuators/{seeded.actuator_id}").text
    lead = {"name": "fast", "spans": "30-100 flights", "weight": 0.8,
            "weights": {"fast": 0.8, "medium": 0.15, "slow": 0.05}}
    with session_scope(app.state.session_factory) as session:
        latest = session.scalars(select(Prognosis).where(
            Prognosis.actuator_id == seeded.actuator_id).order_by(
            Prognosis.flight_index.desc())).first()
        assert latest is not None
        latest.distribution = {**latest.distribution, "hypothesis": lead}
    page = client.get(f"/actuators/{seeded.actuator_id}").text
    start = page.index('id="rul-hypothesis"')
    line = page[start:page.index("</dd>", start)]
    assert "fast fault, 0.80" in line and "30-100 flights" in line
    assert "medium 0.15" in line  # every hypothesis's weight in its title
    got = client.get(f"/api/v1/actuators/{seeded.actuator_id}/prognoses",
                     headers={"Authorization": f"Bearer {keys['viewer']}"}).json()
    named = [p["distribution"]["hypothesis"] for p in got]
    assert named.count(lead) == 1 and named.count(None) == len(got) - 1


def test_actuator_page_embeds_figures_with_data(client, keys, seeded) -> None:
    sign_in(client, keys["viewer"])
    html = client.get(f"/actuators/{seeded.actuator_id}").text
    for fig in ("fig-cone", "fig-hist", "fig-trends", "fig-confidence", "fig-classes",
                "fig-severity"):
        assert f'data-target="{fig}"' in html
    start = html.index('data-target="fig-cone">') + len('data-target="fig-cone">')
    cone = json.loads(html[start:html.index("</script>", start)])
    names = [t.get("name") for t in cone["data"]]
    assert {"median RUL", "5-95 % band", "true RUL", "true RUL ±20 %"} <= set(names)
    assert "/static/vendor/plotly.min.js" in html
    models = client.get("/models").text
    assert 'data-target="fig-confusion"' in models and "per-class" in models


def test_plotly_js_and_static_assets_are_served_locally(client) -> None:
    r = client.get("/static/vendor/plotly.min.js")
    assert r.status_code == 200 and len(r.content) > 1_000_000
    assert client.get("/static/app.js").status_code == 200
    assert client.get("/static/app.css").status_code == 200


def test_viewer_cannot_acknowledge_or_inject(client, keys, seeded, aircraft) -> None:
    sign_in(client, keys["viewer"])
    token = csrf_token(keys["viewer"])
    r = client.post(f"/alarms/{seeded.alarm_id}/acknowledge", data={"note": "x", "csrf": token})
    assert r.status_code == 403
    r = client.post("/test-station/injections", data={
        "csrf": token, "aircraft": aircraft, "position": "WT", "fault_mode": "SE"})
    assert r.status_code == 403
    # and the JSON API refuses the same with the cookie
    r = client.post(f"/api/v1/alarms/{seeded.alarm_id}/acknowledge", json={"note": "x"})
    assert r.status_code == 403


def test_csrf_token_and_origin_are_checked(client, keys, seeded) -> None:
    sign_in(client, keys["admin"])
    url = f"/alarms/{seeded.alarm_id}/acknowledge"
    assert client.post(url, data={"note": "x"}).status_code == 403
    assert client.post(url, data={"note": "x", "csrf": "0" * 64}).status_code == 403
    r = client.post(url, data={"note": "x", "csrf": csrf_token(keys["admin"])},
                    headers={"Origin": "https://evil.example"})
    assert r.status_code == 403
    with session_scope(client.app.state.session_factory) as s:
        assert s.get(Alarm, seeded.alarm_id).status == "open"


def test_admin_acknowledges_then_closes_with_notes(client, keys, seeded) -> None:
    sign_in(client, keys["admin"])
    token = csrf_token(keys["admin"])
    r = client.post(f"/alarms/{seeded.alarm_id}/acknowledge",
                    data={"note": "inspect <rod end>", "csrf": token, "back": "/alarms"},
                    headers={"Origin": "http://testserver"}, follow_redirects=False)
    assert r.status_code == 303 and r.headers["location"] == "/alarms"
    page = client.get("/alarms").text
    assert "inspect &lt;rod end&gt;" in page  # escaped
    r = client.post(f"/alarms/{seeded.alarm_id}/close", data={"note": "replaced",
                                                              "csrf": token})
    assert r.status_code == 200  # followed the redirect back to the inbox
    with session_scope(client.app.state.session_factory) as s:
        row = s.get(Alarm, seeded.alarm_id)
        assert row.status == "closed" and row.closed_by == "test-admin"
        assert row.note == "inspect <rod end>\nreplaced"
    r = client.post(f"/alarms/{seeded.alarm_id}/close", data={"csrf": token})
    assert r.status_code == 409


def test_operator_injects_and_sees_it_listed_errors_are_shown(client, keys, aircraft) -> None:
    sign_in(client, keys["operator"])
    token = csrf_token(keys["operator"])
    r = client.post("/test-station/injections", data={
        "csrf": token, "aircraft": aircraft, "position": "WL2", "fault_mode": "MTWEAR",
        "onset_flight": "3", "time_to_failure_flights": "120"})
    assert r.status_code == 200 and 'id="injection-1"' in r.text and "MTWEAR" in r.text
    r = client.post("/test-station/injections", data={
        "csrf": token, "aircraft": aircraft, "position": "WL2", "fault_mode": "MTWEAR",
        "onset_flight": "5"})
    assert r.status_code == 409 and "already has a live MTWEAR injection" in r.text
    r = client.post("/test-station/injections", data={
        "csrf": token, "aircraft": aircraft, "position": "WT", "fault_mode": "SE",
        "time_to_failure_flights": "3"})
    assert r.status_code == 422
    with session_scope(client.app.state.session_factory) as s:
        assert len(s.scalars(select(Injection)).all()) == 1
    # a second fault on another actuator flies concurrently: both listed
    r = client.post("/test-station/injections", data={
        "csrf": token, "aircraft": aircraft, "position": "WT", "fault_mode": "SE"})
    assert r.status_code == 200 and 'id="injection-1"' in r.text and 'id="injection-2"' in r.text


def test_admin_replaces_actuator_and_history_shows_previous(client, keys, seeded) -> None:
    sign_in(client, keys["admin"])
    r = client.post(f"/actuators/{seeded.actuator_id}/replace", data={
        "csrf": csrf_token(keys["admin"]), "new_serial": "NEW-001", "work_order": "WO-77",
        "note": "worn rod end"}, follow_redirects=False)
    assert r.status_code == 303
    page = client.get(r.headers["location"]).text
    assert "NEW-001" in page and "worn rod end" in page and "WO-77" in page
    assert 'id="maintenance-trail"' in page and "test-admin" in page


def test_maintenance_forms_validate_and_need_the_maintain_role(client, keys, seeded) -> None:
    url = f"/actuators/{seeded.actuator_id}"
    sign_in(client, keys["viewer"])
    r = client.post(url + "/inspect", data={"csrf": csrf_token(keys["viewer"]),
                                            "work_order": "WO-1"})
    assert r.status_code == 403
    client.cookies.clear()
    sign_in(client, keys["operator"])  # the test station's role records no maintenance
    assert 'id="inspect-form"' not in client.get(url).text
    r = client.post(url + "/inspect", data={"csrf": csrf_token(keys["operator"]),
                                            "work_order": "WO-1"})
    assert r.status_code == 403
    client.cookies.clear()
    sign_in(client, keys["maintainer"])
    token = csrf_token(keys["maintainer"])
    page = client.get(url).text
    assert 'id="inspect-form"' in page and 'id="defer-form"' in page
    r = client.post(url + "/replace", data={"csrf": token, "new_serial": "NEW-2",
                                            "work_order": "no spaces allowed"})
    assert r.status_code == 422 and "work_order" in r.text
    r = client.post(url + "/defer", data={"csrf": token, "work_order": "MEL-1",
                                          "reason": "parts on order", "until": "2099-01-31"},
                    follow_redirects=False)
    assert r.status_code == 303
    page = client.get(url).text
    assert "deferred" in page and "MEL-1" in page and "2099-01-31" in page
    r = client.post(url + "/inspect", data={"csrf": token, "work_order": "WO-2",
                                            "note": "no play found"}, follow_redirects=False)
    assert r.status_code == 303
    page = client.get(url).text
    assert "no fault found" in page and 'id="inspect-form"' not in page


def test_evaluation_page_reads_latest_json_or_says_not_run(client, keys, app) -> None:
    sign_in(client, keys["viewer"])
    page = client.get("/evaluation").text
    assert 'id="not-run"' in page and "0.82" in page and "81.2" in page
    path = app.state.settings.data_dir / "evaluation" / "latest.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps({"prognosis": {"DMD": {"ph": 0.64, "ra": 0.713, "ph_cone": 0.5}},
                                "campaign": {"kind": "verification", "seed": 2,
                                             "scale": "quick", "render_every": 20,
                                             "patterns": 31},
                                "created_at": "2026-12-01T06:38:06+00:00"}))
    page = client.get("/evaluation").text
    assert 'id="not-run"' not in page and "71.3" in page
    assert "PH (Saxena, ±0.2·life)" in page and "PH cone (±20 %)" in page

    def dmd_cells(page: str) -> list[str]:
        row = page[page.index('<th scope="row">DMD</th>'):]
        row = row[:row.index("</tr>")]
        return [c.split(">", 1)[1].split("<", 1)[0] for c in row.split("<td")[1:]]

    # paper PH, paper RA, ours: Saxena's PH (headline), the cone's, RA
    assert dmd_cells(page) == ["0.55", "75.3", "0.64", "0.50", "71.3"]
    assert "verification campaign, seed 2, quick scale, 1 in 20 flights of a fault run" in page
    assert "evaluated 2026-12-01T06:38" in page
    # a document written before the rename: the cone's horizon as "ph", Saxena's as "ph_band"
    path.write_text(json.dumps({"prognosis": {"DMD": {"ph": 0.5, "ra": 0.713,
                                                      "ph_band": 0.64}}}))
    assert dmd_cells(client.get("/evaluation").text) == ["0.55", "75.3", "0.64", "0.50", "71.3"]


def test_events_stream_needs_a_key_and_reports_new_alarms(client, keys, seeded, aircraft
                                                          ) -> None:
    assert client.get("/api/v1/events?timeout=1").status_code == 401
    sign_in(client, keys["viewer"])
    factory = client.app.state.session_factory
    import threading

    timer = threading.Timer(0.6, add_alarm, args=(factory,),
                            kwargs={"tail": aircraft, "position": "WT"})
    timer.start()
    with client.stream("GET", "/api/v1/events?timeout=2&poll=0.3") as r:
        assert r.status_code == 200
        assert r.headers["content-type"].startswith("text/event-stream")
        body = "".join(r.iter_text())
    timer.join()
    assert "event: hello" in body
    assert "event: alarm\n" in body and "event: alarm-status" in body


def _fleet(factory, n: int) -> None:  # type: ignore[no-untyped-def]
    with session_scope(factory) as s:
        for i in range(n):
            ac = Aircraft(tail=f"N{i:03d}", base=("Turin", "Naples", "Rome")[i % 3])
            s.add(ac)
            for p in ("WL1", "WL2", "WT"):
                s.add(Actuator(aircraft=ac, position=p, serial=f"S-{i:03d}-{p}"))
        s.flush()
        acts = s.scalars(select(Actuator)).all()
        for k, act in enumerate(acts):
            s.add(ActuatorState(actuator_id=act.id, flights_seen=50, detection={
                "confidence": 0.1}))
            if k % 7 == 0:
                f = Flight(aircraft_id=act.aircraft_id, tail="x", flight_code=f"F{k}",
                           status="analyzed", reasons=[], sha256=f"{k:064d}", size_bytes=1,
                           blob_path="x", content_kind="seed", flight_metadata={})
                s.add(f)
                s.flush()
                s.add(Alarm(actuator_id=act.id, flight_id=f.id, status="open",
                            confidence=0.99, fault_mode="DMD", features=[],
                            rul_median_flights=float(k % 60)))


def test_fleet_page_100_aircraft_by_3_actuators(client, keys, capsys) -> None:
    _fleet(client.app.state.session_factory, 100)
    sign_in(client, keys["viewer"])
    engine = client.app.state.engine
    statements: list[str] = []

    def count(conn, cursor, statement, *args):  # type: ignore[no-untyped-def]
        statements.append(statement)

    client.get("/fleet")  # warm up templates
    event.listen(engine, "before_cursor_execute", count)
    try:
        t0 = time.perf_counter()
        r = client.get("/fleet?sort=rul")
        elapsed = time.perf_counter() - t0
    finally:
        event.remove(engine, "before_cursor_execute", count)
    assert r.status_code == 200
    assert r.text.count('class="cell ') == 300
    assert len(statements) <= 5, statements  # key lookup, the grid's two, the failed flights
    with capsys.disabled():
        print(f"\n[fleet page] 100 aircraft x 3 actuators rendered in {1000 * elapsed:.0f} ms "
              f"with {len(statements)} SQL statements")
    log.info("fleet page 100x3: %.0f ms", 1000 * elapsed)
    # sorted by RUL: the first row holds the shortest median RUL (0 flights)
    first = r.text.index("<tbody>")
    assert ">0<" in r.text[first:first + 2500].replace(" ", "").replace("\n", "")
    by_base = client.get("/fleet?sort=tail&base=Rome&status=yellow")  # DMD alarms: monitor
    assert by_base.status_code == 200 and "N002" in by_base.text and "N000" not in by_base.text
