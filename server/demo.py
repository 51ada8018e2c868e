"""``hmsm demo``: the whole system on one machine with the embedded database.

Upgrades the database, activates the shipped demo model if no usable model is active
(:mod:`server.demo_model`; ``--train`` simulates a quick design campaign and trains one
instead), registers the simulated fleet with a few faults already injected, then runs the API,
one analysis worker and the sim worker together and prints the URL and the keys. In the
background, at low priority, it simulates a small verification campaign and evaluates the
active model on it (:mod:`server.demo_evaluation`), which fills the evaluation page.

The sim worker gets the uploader and operator keys in its environment, never on its command
line (where ``ps`` shows them); the fleet is registered here, so it needs no admin key.
Disk: the demo keeps the raw logs of the last ``DEMO_RAW_KEEP_FLIGHTS`` flights of each
aircraft, healthy or in alarm, and of the flights that raised an alarm or made one of its
last class changes
(``HMSM_RAW_RETENTION_FLIGHTS``, :mod:`server.services.retention`): once every aircraft has
flown that many, the flight logs grow only by those turning points, in alarm or not.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

from sqlalchemy import select
from sqlalchemy.orm import Session, sessionmaker

from server.config import Settings

__all__ = ["DEMO_INJECTIONS", "DEMO_RAW_KEEP_FLIGHTS", "prepare_demo", "run_demo",
           "start_child"]

#: raw logs of its latest flights the demo keeps per aircraft, besides its alarms' turning
#: points (the rest are pruned after analysis): 10 x about 1.8 MB
DEMO_RAW_KEEP_FLIGHTS = 10

# (tail, position, mode, onset flight, flights to failure). Lives in the lower part of the
# design campaign's 30-1000 flights (the envelope the model's degradation priors span): at the
# default 60 flights a minute (6 per aircraft) alarms come within minutes, RUL cones
# right after, and failures -- which reveal the true RUL in hindsight -- in about half an hour.
# Onsets come after the 6 reference flights from which detection learns each actuator's own
# healthy offsets (server/phm/detection/statistics.py), as in the campaigns (8 healthy flights
# first).
DEMO_INJECTIONS = [
    ("SIM01", "WL1", "MTWEAR", 9, 170),
    ("SIM02", "WT", "DMD", 9, 180),
    ("SIM04", "WL2", "REWEAR", 8, 160),
    ("SIM06", "WT", "BDO", 10, None),
    ("SIM08", "WL1", "TTS", 9, 170),
]


def prepare_demo(settings: Settings, *, n_aircraft: int, seed: int, train: bool = False
                 ) -> dict[str, str]:
    """Model, fleet, injections and keys; return the keys by role."""
    from server.auth import create_key
    from server.db import make_engine, make_session_factory, session_scope
    from server.errors import Conflict
    from server.migrate import ensure_schema
    from server.models import ROLES, Aircraft
    from server.schemas import InjectionCreate
    from server.services import fleet, station
    from server.services import models as model_service
    from sim_worker.service import fleet_plan

    settings.data_dir.mkdir(parents=True, exist_ok=True)
    engine = make_engine(settings.effective_database_url)
    ensure_schema(engine, settings.effective_database_url, auto_upgrade=True)
    factory = make_session_factory(engine)
    with factory() as session:
        # a model the chain cannot load (an older chain's format) cannot analyse flights
        try:
            usable = model_service.active_model(session=session) is not None
        except ValueError:
            usable = False
    if not usable and train:
        _train_demo_model(settings, factory, seed)
    elif not usable:
        from server.demo_model import DESIGN_SCALE, DESIGN_SEED, load_demo_model

        doc = load_demo_model()
        with session_scope(factory) as session:
            model_service.store_trained(
                session=session, name=f"demo (shipped: {DESIGN_SCALE} design seed {DESIGN_SEED})",
                payload=doc["payload"], report=doc["training"], make_active=True)
    with session_scope(factory) as session:
        for aircraft in fleet_plan(n_aircraft, seed):
            if session.scalar(select(Aircraft.id).where(Aircraft.tail == aircraft.tail)) is None:
                fleet.create_aircraft(session=session, tail=aircraft.tail, base=aircraft.base,
                                      serials=dict(aircraft.serials))
    for tail, position, mode, onset, ttf in DEMO_INJECTIONS:
        if int(tail[3:]) > n_aircraft:
            continue
        with factory() as session:
            try:
                station.create(session=session, kind=station.FAULTS, created_by="demo",
                               spec=InjectionCreate(aircraft=tail, position=position,
                                                    fault_mode=mode, onset_flight=onset,
                                                    time_to_failure_flights=ttf,
                                                    severity=None))
                session.commit()
            except Conflict as exc:  # already injected on an earlier run of the demo
                if exc.code != "injection_exists":
                    raise
                session.rollback()
    keys: dict[str, str] = {}
    with session_scope(factory) as session:
        for role in reversed(ROLES):  # admin first: the key to sign in with
            keys[role] = create_key(session=session, name=f"demo-{role}", role=role)[1]
    engine.dispose()
    return keys


def _train_demo_model(settings: Settings, factory: sessionmaker[Session], seed: int) -> None:
    """``--train``: simulate a quick design campaign (reused when present) and train on it."""
    from tqdm import tqdm

    from server.db import session_scope
    from server.jobs.training_job import train_into_version
    from server.services import models as model_service

    design = model_service.campaign_dir(settings.data_dir, "demo-design")
    manifest = design / "manifest.json"
    # campaigns of older simulators lack the healthy lead flights the detector needs
    if not manifest.exists() or "lead_flights" not in json.loads(manifest.read_text()):
        print("simulating a quick design campaign (about 3 minutes on 2 cores)...", flush=True)
        from sim_worker import run_campaign

        run_campaign("design", design, seed=seed, scale="quick", progress=True)
    with session_scope(factory) as session:
        version = model_service.create_version(session=session, name="demo-quick",
                                               training={"campaign": str(design)})
        version_id = version.id
    bar = tqdm(total=100, desc="training the demo model (about 1 minute)", unit="%")

    def progress(stage: str, fraction: float) -> None:
        bar.set_postfix_str(stage)
        bar.update(max(0, int(round(100 * fraction)) - bar.n))

    train_into_version(factory, version_id, design, seed=seed, activate=True,
                       progress=progress)
    bar.close()


def start_child(argv: list[str], *, env: dict[str, str], log: Path, nice: bool = False
                ) -> subprocess.Popen[bytes]:
    """Start one of the demo's processes, its output appended to ``log``, and reap it as soon
    as it ends (a thread waits for it): the background evaluation ends minutes into the demo
    and would otherwise stay a zombie until the demo stops."""
    with open(log, "ab") as out:  # the child has its own descriptor of it
        child = subprocess.Popen(argv, env=env, stdout=out, stderr=subprocess.STDOUT,
                                 preexec_fn=(lambda: os.nice(15)) if nice else None)
    threading.Thread(target=child.wait, name=f"reap-{log.stem}", daemon=True).start()
    return child


def run_demo(settings: Settings, *, host: str, port: int, n_aircraft: int, rate: float,
             seed: int, log_level: str, train: bool = False) -> int:
    import uvicorn

    from server.app import create_app

    keys = prepare_demo(settings, n_aircraft=n_aircraft, seed=seed, train=train)
    os.environ.setdefault("HMSM_RAW_RETENTION_FLIGHTS", str(DEMO_RAW_KEEP_FLIGHTS))
    settings = settings.model_copy(update={"raw_retention_flights": int(
        os.environ["HMSM_RAW_RETENTION_FLIGHTS"])})
    app = create_app(settings)
    url = f"http://{host}:{port}"
    env = {**os.environ, "HMSM_DATA_DIR": str(settings.data_dir)}
    if settings.database_url:
        env["HMSM_DATABASE_URL"] = settings.database_url
    logs = settings.data_dir / "logs"
    logs.mkdir(parents=True, exist_ok=True)
    children: list[subprocess.Popen[bytes]] = []

    def start(name: str, argv: list[str], extra_env: dict[str, str] | None = None,
              nice: bool = False) -> None:
        children.append(start_child(argv, env={**env, **(extra_env or {})},
                                    log=logs / f"{name}.log", nice=nice))

    def stop_children(*_: object) -> None:
        for child in children:
            if child.poll() is None:
                child.terminate()
        for child in children:
            try:
                child.wait(timeout=15)
            except subprocess.TimeoutExpired:
                child.kill()

    start("worker", [sys.executable, "-m", "server.cli", "worker"])
    start("sim-worker", [sys.executable, "-m", "sim_worker.cli", "run", "--api", url,
                         "--aircraft", str(n_aircraft), "--rate", str(rate),
                         "--seed", str(seed), "--duration", "60"],
          {"HMSM_SIM_KEY": keys["uploader"], "HMSM_SIM_OPERATOR_KEY": keys["operator"]})
    start("evaluation", [sys.executable, "-m", "server.demo_evaluation"], nice=True)
    print("\nHMSM demo is running")
    print(f"  dashboard: {url}/            API: {url}/api/v1   OpenAPI: {url}/docs")
    print(f"  data dir:  {settings.data_dir}   logs: {logs}")
    for role, key in keys.items():
        print(f"  {role:10s} key: {key}")
    print(f"  {n_aircraft} simulated aircraft fly {rate:g} flights a minute; faults injected: "
          + ", ".join(f"{t}/{p} {m}" for t, p, m, _, _ in DEMO_INJECTIONS
                      if int(t[3:]) <= n_aircraft))
    print("  the evaluation page fills in after about 4 minutes on an idle 2-core machine, "
          "longer when it is busy (a small verification campaign is simulated and evaluated "
          "in the background at low priority; the page shows how far it is; "
          "logs/evaluation.log)")
    print(f"  raw logs: the last {settings.raw_retention_flights} flights of each aircraft and "
          "the flights that raised or changed an alarm are kept")
    print("  Ctrl-C stops everything.\n", flush=True)
    def _terminate(*_: object) -> None:
        raise KeyboardInterrupt  # uvicorn stops, then the finally block stops the children

    signal.signal(signal.SIGTERM, _terminate)
    try:
        uvicorn.run(app, host=host, port=port, log_level=log_level,
                    **settings.server_options())
    finally:
        stop_children()
        time.sleep(0.1)
    return 0
