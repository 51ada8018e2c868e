"""The ``hmsm`` command: database, keys, the API server and the demo."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from typing import TYPE_CHECKING

from server.config import Settings, load_settings

if TYPE_CHECKING:  # pragma: no cover - typing only
    from server.campaign_store import CampaignStore

__all__ = ["main"]


def _session(settings: Settings):
    from server.db import make_engine, make_session_factory
    from server.migrate import ensure_schema

    settings.data_dir.mkdir(parents=True, exist_ok=True)
    engine = make_engine(settings.effective_database_url)
    ensure_schema(engine, settings.effective_database_url, auto_upgrade=settings.is_sqlite)
    return make_session_factory(engine)


def cmd_db(args: argparse.Namespace, settings: Settings) -> int:
    from server import migrate

    settings.data_dir.mkdir(parents=True, exist_ok=True)
    url = settings.effective_database_url
    if args.action == "upgrade":
        migrate.upgrade(url, args.revision or "head")
    elif args.action == "downgrade":
        migrate.downgrade(url, args.revision or "base")
    from server.db import make_engine

    engine = make_engine(url)
    print(f"schema revision: {migrate.current_revision(engine) or 'none'} "
          f"(code head: {migrate.head_revision()})")
    engine.dispose()
    return 0


def cmd_store(args: argparse.Namespace, settings: Settings) -> int:
    """Make the blob store ready: the directories, and the bucket of HMSM_BLOB_URL unless it
    exists, waiting up to ``--wait`` seconds for the object store to answer (it may start
    beside us, as in docker-compose.yml)."""
    import time

    from server.blobstore import BlobStoreUnreachable
    from server.blobstore_factory import open_blob_store

    store = open_blob_store(settings)
    if settings.blob_url is None:
        print(f"blob store: {settings.blob_dir}")
        return 0
    from server.blobstore_s3 import S3BlobStore

    assert isinstance(store, S3BlobStore)
    deadline = time.monotonic() + args.wait
    while True:
        try:
            created = store.ensure_bucket()
            break
        except BlobStoreUnreachable as exc:
            if time.monotonic() > deadline:
                print(f"hmsm: the object store does not answer: {exc}", file=sys.stderr)
                return 2
            time.sleep(2)
    print(f"blob store: {settings.blob_url} (bucket {'created' if created else 'exists'})")
    return 0


def cmd_keys(args: argparse.Namespace, settings: Settings) -> int:
    from server.auth import create_key, list_keys, revoke_key
    from server.db import session_scope

    factory = _session(settings)
    with session_scope(factory) as session:
        if args.action == "create":
            row, plaintext = create_key(session=session, name=args.name, role=args.role)
            print(f"created key {row.id} ({row.role}, {row.name}); it is shown only once:")
            print(plaintext)
        elif args.action == "revoke":
            row = revoke_key(session=session, key_id=args.id)
            print(f"revoked key {row.id} ({row.name})")
        else:
            for row in list_keys(session=session):
                state = "revoked" if row.revoked_at else "active"
                print(f"{row.id:4d}  {row.role:8s}  {state:7s}  {row.prefix}...  {row.name}")
    return 0


def cmd_serve(args: argparse.Namespace, settings: Settings) -> int:
    import uvicorn

    from server.app import create_app

    app = create_app(settings)
    host = args.host or settings.host
    port = args.port if args.port is not None else settings.port
    uvicorn.run(app, host=host, port=port, log_level=args.log_level,
                **settings.server_options())
    return 0


def cmd_demo(args: argparse.Namespace, settings: Settings) -> int:
    from server.demo import run_demo

    if not settings.is_sqlite:
        print("hmsm: the demo runs on the embedded SQLite database; unset HMSM_DATABASE_URL",
              file=sys.stderr)
        return 2
    return run_demo(settings, host=args.host or settings.host,
                    port=args.port if args.port is not None else settings.port,
                    n_aircraft=args.aircraft, rate=args.rate, seed=args.seed,
                    log_level=args.log_level, train=args.train)


def cmd_demo_model(args: argparse.Namespace, settings: Settings) -> int:
    from server.demo_model import DESIGN_SCALE, DESIGN_SEED, TRAINING_SEED, write_demo_model

    doc = write_demo_model(args.out, campaign=args.campaign, jobs=args.jobs)
    print(f"demo model ({DESIGN_SCALE} design campaign seed {DESIGN_SEED}, training seed "
          f"{TRAINING_SEED}, {doc['training']['campaign']['flights']} flights) written to "
          f"{args.out}")
    return 0


def cmd_worker(args: argparse.Namespace, settings: Settings) -> int:
    import logging
    import multiprocessing
    import signal

    from server.jobs.worker import run_worker_process

    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s %(message)s")
    if args.concurrency == 1:
        run_worker_process(settings, args.lease, args.exit_when_idle)
        return 0
    ctx = multiprocessing.get_context("spawn")
    procs = [ctx.Process(target=run_worker_process, name=f"hmsm-worker-{i}",
                         args=(settings, args.lease, args.exit_when_idle))
             for i in range(args.concurrency)]
    for p in procs:
        p.start()

    def _forward(*_: object) -> None:
        for p in procs:
            p.terminate()

    signal.signal(signal.SIGTERM, _forward)
    signal.signal(signal.SIGINT, _forward)
    for p in procs:
        p.join()
    return 0


def _train_to_file(design: CampaignStore, args: argparse.Namespace) -> int:
    """``hmsm train DIR --out FILE``: the model document written to a file (the shape of a
    protocol run's ``model.json``), no database."""
    import json
    from pathlib import Path

    from server.campaigns import read_manifest, train_from_directory
    from server.demo_model import TRAINED_MODEL_FORMAT, trained_model_document

    manifest = read_manifest(design)
    model, report = train_from_directory(design, seed=args.seed)
    doc = trained_model_document(TRAINED_MODEL_FORMAT, {k: manifest.get(k) for k in
                                                ("kind", "scale", "seed", "span_flights")},
                                 args.seed, model.to_dict(), report)
    out = Path(args.out)
    tmp = out.with_suffix(".part")
    tmp.write_text(json.dumps(doc, sort_keys=True, separators=(",", ":")) + "\n")
    tmp.replace(out)
    print(f"model trained on {design} written to {out}")
    return 0


def cmd_train(args: argparse.Namespace, settings: Settings) -> int:
    from tqdm import tqdm

    from server.campaigns import campaign_store
    from server.jobs.training_job import train_into_version
    from server.services import models as service

    design = campaign_store(args.campaign_dir)  # a directory or s3://bucket/prefix
    if not design.exists("manifest.json"):
        print(f"hmsm: {design} has no manifest.json; make one with "
              "`sim-worker campaign --kind design --out DIR`", file=sys.stderr)
        return 2
    if args.out is not None:
        return _train_to_file(design, args)
    factory = _session(settings)
    with factory() as session:
        version = service.create_version(session=session,
                                         name=args.name or design.root.rsplit("/", 1)[-1],
                                         training={"campaign": str(design)})
        session.commit()
        version_id = version.id
    bar = tqdm(total=100, desc="training", unit="%", disable=args.no_progress)

    def progress(stage: str, fraction: float) -> None:
        bar.set_postfix_str(stage)
        bar.update(max(0, int(round(100 * fraction)) - bar.n))

    report = train_into_version(factory, version_id, design, seed=args.seed,
                                activate=not args.no_activate, progress=progress)
    bar.close()
    conf = report["classifier"]["confusion"]
    print(f"model version {version_id} ({'active' if not args.no_activate else 'inactive'}): "
          f"held-out accuracy {100 * conf['accuracy']:.1f} % on "
          f"{report['classifier']['n_test']} flights of "
          f"{len(report['classifier']['test_groups'])} patterns")
    classes = conf["classes"]
    print("confusion (rows true, columns predicted, %):")
    print("        " + " ".join(f"{c:>7s}" for c in classes))
    for c, row in zip(classes, conf["rates"], strict=True):
        print(f"{c:>7s} " + " ".join("      -" if v is None else f"{100 * v:7.1f}" for v in row))
    print("measurement features: " + ", ".join(
        f"{m}->{r['feature']} (rho {r['spearman']:+.2f})"
        for m, r in report["measurement"].items()))
    return 0


def cmd_campaign(args: argparse.Namespace, settings: Settings) -> int:
    import time

    from server.campaigns import FeatureSink
    from sim_worker.cli import run_campaign_command

    t0 = time.perf_counter()
    manifest = run_campaign_command(args, sink=FeatureSink(keep_raw_every=args.keep_raw_every),
                                    endpoint=settings.s3_endpoint_url)
    flights = [f for p in manifest["patterns"] for f in p["flights"]]
    kept = sum(1 for f in flights if f["file"])
    print(f"{args.kind} campaign: {len(manifest['patterns'])} patterns, {len(flights)} flights "
          f"streamed ({kept} logs kept) to {args.out} in {time.perf_counter() - t0:.1f} s")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="hmsm", description="EMA health management service.")
    sub = parser.add_subparsers(dest="command", required=True)

    db = sub.add_parser("db", help="database schema (Alembic)")
    db.add_argument("action", choices=["upgrade", "downgrade", "current"])
    db.add_argument("revision", nargs="?", help="target revision (default head / base)")
    db.set_defaults(func=cmd_db)

    store = sub.add_parser("store", help="the flight-log store (HMSM_BLOB_URL)")
    store.add_argument("action", choices=["init"], help="create the bucket unless it exists")
    store.add_argument("--wait", type=float, default=60.0,
                       help="seconds to wait for the object store to answer")
    store.set_defaults(func=cmd_store)

    from server.models import ROLES

    keys = sub.add_parser("keys", help="API keys")
    kact = keys.add_subparsers(dest="action", required=True)
    kc = kact.add_parser("create", help="create a key and print it once")
    kc.add_argument("--role", required=True, choices=ROLES)
    kc.add_argument("--name", required=True)
    kr = kact.add_parser("revoke", help="revoke a key")
    kr.add_argument("id", type=int)
    kact.add_parser("list", help="list keys")
    keys.set_defaults(func=cmd_keys)

    train = sub.add_parser("train", help="train a model version from a design campaign")
    train.add_argument("campaign_dir", help="design campaign directory (sim-worker campaign), "
                       "or s3://bucket/prefix")
    train.add_argument("--seed", type=int, default=0, help="seed of the 70/30 split")
    train.add_argument("--name", default=None, help="model version name")
    train.add_argument("--no-activate", action="store_true", help="do not make it active")
    train.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    train.add_argument("--out", default=None, metavar="FILE",
                       help="write the model document to FILE instead of the database")
    train.set_defaults(func=cmd_train)

    from server.evaluation.band_calibration import add_calibrate_arguments, run_calibrate

    calibrate = sub.add_parser("calibrate", help="fit the RUL bands' calibration layer on "
                               "replays of calibration design runs (hmsm evaluate)")
    add_calibrate_arguments(calibrate)
    calibrate.set_defaults(func=run_calibrate)

    from server.evaluation.cli import add_evaluate_arguments, run_evaluate

    evaluate = sub.add_parser("evaluate", help="evaluate the PHM chain on a verification "
                              "campaign (paper section 5): JSON + HTML report")
    add_evaluate_arguments(evaluate)
    evaluate.set_defaults(func=run_evaluate)

    from sim_worker.cli import add_campaign_arguments

    campaign = sub.add_parser("campaign", help="stream a simulated campaign: every flight "
                              "simulated, its features kept, its log only for a sample")
    add_campaign_arguments(campaign)
    campaign.add_argument("--keep-raw-every", type=int, default=200, metavar="K",
                          help="keep the flight log of every K-th flight of a pattern "
                          "(default 200: about 1 GB for the protocol scale; 1 keeps every one)")
    campaign.set_defaults(func=cmd_campaign)

    from server.evaluation.protocol import add_protocol_arguments, run_protocol

    protocol = sub.add_parser("protocol", help="the paper's assessment from nothing: stream a "
                              "design and a verification campaign, train, evaluate")
    add_protocol_arguments(protocol)
    protocol.set_defaults(func=run_protocol)

    demo_model = sub.add_parser("demo-model", help="regenerate the model the demo ships with "
                                "(server/data/demo_model.json): stream the shipped design "
                                "campaign of seed 1 (16 minutes on 2 idle cores) and train on "
                                "it; hmsm calibrate then adds the RUL bands' layers "
                                "(bench/rul_suite.py calibrate)")
    demo_model.add_argument("--out", required=True, help="JSON file to write")
    demo_model.add_argument("--campaign", default=None,
                            help="reuse this streamed shipped design campaign of seed 1 "
                            "instead of simulating it")
    demo_model.add_argument("--jobs", type=int, default=None, help="worker processes")
    demo_model.set_defaults(func=cmd_demo_model)

    worker = sub.add_parser("worker", help="run analysis workers")
    worker.add_argument("--concurrency", type=int, default=1, help="worker processes")
    worker.add_argument("--lease", type=float, default=120.0, help="job lease [s]")
    worker.add_argument("--exit-when-idle", action="store_true",
                        help="stop when the queue is empty (batch use)")
    worker.set_defaults(func=cmd_worker)

    for name, func, text in (("serve", cmd_serve, "run the API server"),
                             ("demo", cmd_demo, "run the demo on the embedded database")):
        p = sub.add_parser(name, help=text)
        p.add_argument("--host", default=None, help="bind address (default HMSM_HOST, 127.0.0.1)")
        p.add_argument("--port", type=int, default=None, help="port (default HMSM_PORT, 8000)")
        p.add_argument("--log-level", default="info" if name == "serve" else "warning")
        if name == "demo":
            p.add_argument("--aircraft", type=int, default=10, help="simulated aircraft")
            p.add_argument("--rate", type=float, default=60.0, help="flights per minute")
            p.add_argument("--seed", type=int, default=1)
            p.add_argument("--train", action="store_true",
                           help="train the demo model from a freshly simulated quick design "
                           "campaign (about 4 minutes on 2 cores) instead of starting on the "
                           "shipped one; its healthy cycles are 12 flights of 60 s in one "
                           "season, so it alarms on healthy units over long lives and under "
                           "the test station's conditions where the shipped one does not")
        p.set_defaults(func=func)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    from sqlalchemy.exc import OperationalError

    from server.migrate import SchemaBehindError

    args = build_parser().parse_args(argv)
    try:
        settings = load_settings()
    except Exception as exc:  # pydantic ValidationError: show it plainly
        print(f"hmsm: bad configuration: {exc}", file=sys.stderr)
        return 2
    try:
        return int(args.func(args, settings) or 0)
    except SchemaBehindError as exc:
        print(f"hmsm: {exc}", file=sys.stderr)
        return 2
    except OperationalError as exc:
        print(f"hmsm: cannot reach the database: {exc.orig}", file=sys.stderr)
        return 2
    except ValueError as exc:
        print(f"hmsm: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
