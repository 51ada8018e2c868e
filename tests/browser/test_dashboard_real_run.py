"""The dashboard on the results of a real run: the simulated fleet flies injected faults, the
analysis worker runs the trained model, and an engineer follows one actuator from alarm to
fault class to RUL cone in Chromium. Nothing is written behind the pipeline's back."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from collections.abc import Iterator

import httpx
import pytest
from sqlalchemy import create_engine

from server.auth import create_key
from server.config import Settings
from server.db import make_session_factory, session_scope
from server.migrate import upgrade
from server.services import models as model_service
from sim_worker.service import Api, SimFleetRunner
from tests.browser.test_dashboard import (
    ARGS,
    CHROMIUM,
    NEEDS_CHROMIUM,
    Console,
    _plot_points,
    _shot,
    _sign_in,
)
from tests.live_server import running_server

# without Chromium the test skips, like the other browser tests, instead of erroring
pytestmark = [pytest.mark.slow, NEEDS_CHROMIUM]


@pytest.fixture(scope="module")
def real_run(tmp_path_factory: pytest.TempPathFactory, shipped_model) -> Iterator[dict]:  # type: ignore[no-untyped-def]
    data_dir = tmp_path_factory.mktemp("real-run") / "data"
    data_dir.mkdir(parents=True)
    settings = Settings(data_dir=data_dir)
    upgrade(settings.effective_database_url)
    engine = create_engine(settings.effective_database_url)
    with session_scope(make_session_factory(engine)) as s:
        model_service.store_trained(session=s, name="real-run", payload=shipped_model[0],
                                    report=shipped_model[1], make_active=True)
        keys = {r: create_key(session=s, name=f"eng-{r}", role=r)[1]
                for r in ("admin", "operator", "viewer")}
    engine.dispose()
    env = {"HMSM_DATA_DIR": str(data_dir)}
    with running_server(env) as url:
        worker = subprocess.Popen([sys.executable, "-m", "server.cli", "worker"],
                                  env={**os.environ, **env}, stdout=subprocess.DEVNULL,
                                  stderr=subprocess.DEVNULL)
        try:
            runner = SimFleetRunner(Api(url, keys["admin"]), n_aircraft=2, rate_per_min=1e6,
                                    seed=21, duration_s=60)
            runner.register_fleet()
            op = {"Authorization": f"Bearer {keys['operator']}"}
            for body in ({"aircraft": "SIM01", "position": "WT", "fault_mode": "BDO",
                          "onset_flight": 2},
                         {"aircraft": "SIM02", "position": "WL1", "fault_mode": "MTWEAR",
                          "onset_flight": 1, "time_to_failure_flights": 24}):
                assert httpx.post(f"{url}/api/v1/test-station/injections", json=body,
                                  headers=op).status_code == 201
            runner.run(max_flights=2 * 14)
            viewer = {"Authorization": f"Bearer {keys['viewer']}"}
            deadline = time.monotonic() + 240
            while httpx.get(f"{url}/api/v1/flights?status=analyzed&limit=1",
                            headers=viewer).json()["total"] < 28:
                assert time.monotonic() < deadline, "analysis did not finish"
                time.sleep(0.3)
            yield {"url": url, "keys": keys}
        finally:
            worker.terminate()
            worker.wait(timeout=30)


def test_engineer_follows_an_actuator_from_alarm_to_rul_cone(real_run, browser) -> None:  # type: ignore[no-untyped-def]
    url, keys = real_run["url"], real_run["keys"]
    context = browser.new_context(viewport={"width": 1280, "height": 800})
    page = context.new_page()
    console = Console(page)
    _sign_in(page, url, keys["admin"])
    # the BDO drive is red (replace now); the wear alarm amber or yellow by its 5 % RUL
    assert page.locator("#fleet-grid tbody td.cell.red").count() >= 1
    cells = page.locator("#fleet-grid tbody td.cell.amber, #fleet-grid tbody td.cell.red, "
                         "#fleet-grid tbody td.cell.yellow")
    assert cells.count() >= 2, page.locator("#fleet-grid").inner_text()
    _shot(page, "real-fleet-1280")

    api = {"Authorization": f"Bearer {keys['viewer']}"}
    alarms = {(a["aircraft"], a["position"]): a for a in
              httpx.get(f"{url}/api/v1/alarms", headers=api).json()["items"]}
    bdo, wear = alarms[("SIM01", "WT")], alarms[("SIM02", "WL1")]
    assert bdo["fault_mode"] == "BDO" and wear["fault_mode"] == "MTWEAR"

    page.goto(f"{url}/alarms")
    row = page.locator(f"#alarm-{wear['id']}")
    assert "MTWEAR" in row.inner_text()
    page.get_by_label(f"Note for alarm {wear['id']}").fill("backlash check scheduled")
    row.get_by_role("button", name="Acknowledge").click()
    page.wait_for_url(f"{url}/alarms")
    assert "acknowledged" in page.locator(f"#alarm-{wear['id']}").inner_text()
    _shot(page, "real-alarms-1280")

    page.goto(f"{url}/actuators/{wear['actuator_id']}")
    cone = _plot_points(page, "fig-cone")
    assert cone and max(cone) >= 2, cone  # median and band over several predictions
    assert max(_plot_points(page, "fig-classes")) > 0
    _shot(page, "real-actuator-1280")

    page.goto(f"{url}/models")
    assert _plot_points(page, "fig-confusion")
    assert console.errors == [], console.errors
    context.close()


@pytest.fixture(scope="module")
def browser() -> Iterator[object]:
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=ARGS)
        yield b
        b.close()
