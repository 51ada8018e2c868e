"""Cross-site writes through the session cookie, in a real browser (Debian's /usr/bin/chromium,
Playwright) against ``hmsm serve``: a page served on another port of the same host -- the
same *site*, so the ``SameSite=Strict`` cookie goes along -- forges a form post and ``fetch``
calls at the API; the server refuses them, while the signed-in dashboard still writes (its
forms, and the API with the page's CSRF token) and the API docs render under the CSP with
nothing loaded from elsewhere (ReDoc's sidebar asks for Redocly's logo on their CDN: the CSP
blocks it and ReDoc leaves the image out).
"""

from __future__ import annotations

import threading
from collections.abc import Iterator
from dataclasses import dataclass
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

import httpx
import pytest

from server.auth import create_key
from server.config import Settings
from server.db import make_engine, make_session_factory, session_scope
from server.migrate import ensure_schema
from tests.browser.test_dashboard import ARGS, CHROMIUM, NEEDS_CHROMIUM, Console, _sign_in
from tests.flightlog_factory import serials_for
from tests.live_server import running_server

playwright_api = pytest.importorskip("playwright.sync_api", reason="playwright not installed")
pytestmark = [NEEDS_CHROMIUM, pytest.mark.slow]

TAIL = "X001"
REDOCLY_LOGO = "https://cdn.redoc.ly/redoc/logo-mini.svg"
# what a forged upload sends: a CSV flight with its form fields, as a real client would
FORGED_UPLOAD = """
async (api) => {
  const form = new FormData();
  form.append("file", new Blob(["t,WL1.ia\\n0,1\\n"], {type: "text/csv"}), "forged.csv");
  form.append("aircraft", "X001");
  form.append("flight", "FORGED1");
  await fetch(api + "/api/v1/flights",
              {method: "POST", body: form, credentials: "include", mode: "no-cors"});
}
"""
FORGED_REVOKE = """
async ([api, id]) => {
  await fetch(api + "/api/v1/keys/" + id + "/revoke",
              {method: "POST", credentials: "include", mode: "no-cors"});
}
"""
# the dashboard's own script calling the API: the token from the page's meta tag
OWN_REVOKE = """
async (id) => {
  const token = document.querySelector('meta[name="hmsm-csrf"]').content;
  const r = await fetch("/api/v1/keys/" + id + "/revoke",
                        {method: "POST", headers: {"X-CSRF-Token": token}});
  return r.status;
}
"""


@dataclass
class Site:
    url: str
    attacker: str
    admin: str
    victims: dict[str, int]  # key name -> id: the keys the requests try to revoke
    pages: dict[str, bytes]  # the attacker's pages by path (a test may add one)

    def _bearer(self) -> dict[str, str]:
        return {"Authorization": f"Bearer {self.admin}"}

    def revoked(self, name: str) -> bool:
        keys = httpx.get(f"{self.url}/api/v1/keys", headers=self._bearer()).json()
        return next(k for k in keys if k["id"] == self.victims[name])["revoked_at"] is not None

    def flights(self) -> int:
        r = httpx.get(f"{self.url}/api/v1/flights", headers=self._bearer())
        return int(r.json()["total"])


def _attacker_server(pages: dict[str, bytes]) -> ThreadingHTTPServer:
    class Handler(BaseHTTPRequestHandler):
        def do_GET(self) -> None:  # noqa: N802  (http.server's name)
            body = pages.get(self.path, b"<!doctype html><title>blank</title>")
            self.send_response(200)
            self.send_header("Content-Type", "text/html; charset=utf-8")
            self.send_header("Content-Length", str(len(body)))
            self.end_headers()
            self.wfile.write(body)

        def log_message(self, *args: object) -> None:
            pass

    return ThreadingHTTPServer(("127.0.0.1", 0), Handler)


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Site]:
    data_dir = tmp_path_factory.mktemp("cross-site") / "data"
    data_dir.mkdir(parents=True)
    settings = Settings(data_dir=data_dir)
    engine = make_engine(settings.effective_database_url)
    ensure_schema(engine, settings.effective_database_url, auto_upgrade=True)
    with session_scope(make_session_factory(engine)) as session:
        admin = create_key(session=session, name="browser-admin", role="admin")[1]
        victims = {name: create_key(session=session, name=name, role="viewer")[0].id
                   for name in ("form-victim", "fetch-victim", "own-page")}
    engine.dispose()
    with running_server({"HMSM_DATA_DIR": str(data_dir)}) as url:
        r = httpx.post(f"{url}/api/v1/aircraft", headers={"Authorization": f"Bearer {admin}"},
                       json={"tail": TAIL, "base": "Turin", "actuators": serials_for(TAIL)})
        assert r.status_code == 201, r.text
        form = (f'<!doctype html><title>prize</title><form method="post" '
                f'action="{url}/api/v1/keys/{victims["form-victim"]}/revoke">'
                '<button type="submit">Claim your prize</button></form>').encode()
        pages = {"/prize": form}
        attacker = _attacker_server(pages)
        thread = threading.Thread(target=attacker.serve_forever, daemon=True)
        thread.start()
        try:
            yield Site(url=url, attacker=f"http://127.0.0.1:{attacker.server_port}",
                       admin=admin, victims=victims, pages=pages)
        finally:
            attacker.shutdown()
            attacker.server_close()


@pytest.fixture(scope="module")
def browser(site: Site) -> Iterator[object]:
    with playwright_api.sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=ARGS)
        yield b
        b.close()


def test_forged_form_post_and_fetch_from_another_port_are_refused(site: Site, browser
                                                                  ) -> None:  # type: ignore[no-untyped-def]
    context = browser.new_context()
    page = context.new_page()
    _sign_in(page, site.url, site.admin)
    cookie = next(c for c in context.cookies() if c["name"] == "hmsm_session")
    assert cookie["sameSite"] == "Strict" and cookie["domain"] == "127.0.0.1"

    page.goto(f"{site.attacker}/prize")
    with page.expect_navigation():
        page.get_by_role("button", name="Claim your prize").click()
    assert "cross_origin" in page.content()  # the API's refusal, shown in the browser
    assert not site.revoked("form-victim")

    page.goto(f"{site.attacker}/blank")
    page.evaluate(FORGED_REVOKE, [site.url, site.victims["fetch-victim"]])
    page.evaluate(FORGED_UPLOAD, site.url)
    assert not site.revoked("fetch-victim")
    assert site.flights() == 0
    context.close()


def test_forged_signin_from_another_port_is_refused(site: Site, browser) -> None:  # type: ignore[no-untyped-def]
    """Login CSRF: the attacker's page posts the sign-in form with its own key (and hides its
    origin: Origin null); the browser stays signed out, and the real form still signs in."""
    made = httpx.post(f"{site.url}/api/v1/keys", headers=site._bearer(),
                      json={"name": "attacker", "role": "viewer"})
    assert made.status_code == 201, made.text
    site.pages["/welcome"] = (
        '<!doctype html><title>welcome</title><meta name="referrer" content="no-referrer">'
        f'<form method="post" action="{site.url}/signin">'
        f'<input type="hidden" name="key" value="{made.json()["key"]}">'
        '<input type="hidden" name="next" value="/fleet">'
        '<button type="submit">Continue</button></form>').encode()
    context = browser.new_context()
    page = context.new_page()
    page.goto(f"{site.url}/signin")  # the victim's pre-session cookie is there
    page.goto(f"{site.attacker}/welcome")
    with page.expect_navigation():
        page.get_by_role("button", name="Continue").click()
    assert page.url.startswith(site.url) and "Sign-in refused" in page.content()
    assert "hmsm_session" not in {c["name"] for c in context.cookies()}
    _sign_in(page, site.url, site.admin)  # the real form, right after
    assert "browser-admin" in page.content()
    context.close()


def test_the_signed_in_dashboard_still_writes(site: Site, browser) -> None:  # type: ignore[no-untyped-def]
    context = browser.new_context()
    page = context.new_page()
    console = Console(page)
    _sign_in(page, site.url, site.admin)
    page.goto(f"{site.url}/test-station")  # a dashboard form post
    form = page.locator("#inject-form")
    form.get_by_label("Aircraft").select_option(TAIL)
    form.get_by_label("Position").select_option("WT")
    form.get_by_label("Fault mode").select_option("SE")
    page.get_by_role("button", name="Inject fault").click()
    page.wait_for_url(f"{site.url}/test-station")
    assert page.locator("#injection-table tbody tr", has_text=TAIL).count() == 1
    assert page.evaluate(OWN_REVOKE, site.victims["own-page"]) == 200  # the API, from our page
    assert site.revoked("own-page")
    assert console.errors == [], console.errors
    context.close()


def test_api_docs_render_under_the_csp_from_local_assets(site: Site, browser) -> None:  # type: ignore[no-untyped-def]
    context = browser.new_context()
    page = context.new_page()
    console = Console(page)
    requested: list[str] = []
    blocked: list[tuple[str, str | None]] = []
    page.on("request", lambda r: requested.append(r.url))
    page.on("requestfailed", lambda r: blocked.append((r.url, r.failure)))
    _sign_in(page, site.url, site.admin)
    page.goto(f"{site.url}/docs")
    page.locator(".opblock-summary-path", has_text="/api/v1/flights").first.wait_for(
        timeout=15_000)
    sent = page.evaluate("window.ui.getConfigs().requestInterceptor({headers: {}}).headers")
    assert sent == {"X-CSRF-Token": page.locator('meta[name="hmsm-csrf"]').get_attribute(
        "content")}  # "Try it out" writes with the session carry its token
    page.goto(f"{site.url}/redoc")
    page.locator("h2", has_text="Upload a flight log (uploader)").wait_for(timeout=15_000)
    foreign = [u for u in requested if not u.startswith((site.url, "data:"))]
    assert set(foreign) <= {REDOCLY_LOGO}, foreign
    assert all(dict(blocked).get(url) == "csp" for url in foreign), blocked  # never sent
    assert [e for e in console.errors if REDOCLY_LOGO not in e] == [], console.errors
    context.close()


def test_api_docs_fit_a_phone(site: Site, browser) -> None:  # type: ignore[no-untyped-def]
    """A phone lays a page out 980 px wide unless the page asks for its width (the viewport
    meta tag): Swagger UI and ReDoc fit 390 px."""
    context = browser.new_context(viewport={"width": 390, "height": 844}, is_mobile=True,
                                  has_touch=True, device_scale_factor=3)
    page = context.new_page()
    _sign_in(page, site.url, site.admin)
    page.goto(f"{site.url}/docs")
    page.locator(".opblock-summary-path", has_text="/api/v1/flights").first.wait_for(
        timeout=15_000)
    assert page.evaluate("window.innerWidth") == 390
    width = page.evaluate("document.documentElement.scrollWidth")
    assert width <= 420, f"/docs is {width} px wide on a 390 px phone"
    page.goto(f"{site.url}/redoc")
    page.locator("h2", has_text="Upload a flight log (uploader)").wait_for(timeout=15_000)
    assert page.evaluate("window.innerWidth") == 390
    width = page.evaluate("document.documentElement.scrollWidth")
    assert width <= 420, f"/redoc is {width} px wide on a 390 px phone"
    context.close()
