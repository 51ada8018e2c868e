"""``hmsm evaluate``: run the PHM chain over a campaign and write the evaluation.

Usage::

    hmsm evaluate --campaign DIR [--design DIR | --model-json FILE | --model-id N]
                  [--out DIR] [--jobs N] [--seed N] [--no-progress]

Model: ``--model-json`` (a ``ema-phm-model/5`` document, or one wrapped in the ``payload`` of
a model-version export, the demo's model or a protocol run's ``model.json``, whose
``training`` report then goes into the evaluation), ``--model-id`` (a model version of the
database), ``--design`` (train on a design campaign, seed ``--seed``), else the active model
version of the database.

Writes into ``--out`` (default ``<HMSM_DATA_DIR>/evaluation/<UTC timestamp>/``):
``evaluation.json`` (everything, with the per-flight traces), ``summary.json`` (every figure
and its bootstrap interval, no traces: shape in :mod:`server.evaluation.summary`),
``report.html`` (plotly.js embedded once), ``rul_<MODE>.html`` (one page per progressive mode,
with a local ``plotly.min.js``), ``summary.md`` ("mean [lo, hi]" tables); and copies the JSON
to ``<HMSM_DATA_DIR>/evaluation/latest.json`` (read by the dashboard's evaluation page:
``prognosis.<MODE>.ph`` Saxena's nondimensional horizon, ``prognosis.<MODE>.ph_cone`` the
+-20 % cone's, ``prognosis.<MODE>.ra`` relative accuracy in %).

Wiring into ``server/cli.py``::

    from server.evaluation.cli import add_evaluate_arguments, run_evaluate
    ev = sub.add_parser("evaluate", help="evaluate the PHM chain on a campaign")
    add_evaluate_arguments(ev)
    ev.set_defaults(func=run_evaluate)
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import shutil
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from server.config import Settings, load_settings
from server.phm.chain import PhmModel, read_model_document

__all__ = ["add_evaluate_arguments", "run_evaluate", "main_evaluate", "load_model",
           "write_outputs"]


def add_evaluate_arguments(parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
    parser.add_argument("--campaign", required=True, help="campaign directory to evaluate on, "
                        "or s3://bucket/prefix")
    src = parser.add_mutually_exclusive_group()
    src.add_argument("--design", help="train the model on this design campaign first")
    src.add_argument("--model-json", help="model JSON file (ema-phm-model/5)")
    src.add_argument("--model-id", type=int, help="model version id in the database")
    parser.add_argument("--seed", type=int, default=0, help="training seed (with --design)")
    parser.add_argument("--out", help="output directory (default "
                        "<HMSM_DATA_DIR>/evaluation/<timestamp>/)")
    parser.add_argument("--jobs", type=int, default=min(2, os.cpu_count() or 1),
                        help="worker processes over patterns")
    parser.add_argument("--timing-flights", type=int, default=6,
                        help="flights re-read to time feature extraction (0: skip)")
    parser.add_argument("--no-latest", action="store_true",
                        help="do not update <HMSM_DATA_DIR>/evaluation/latest.json")
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    parser.add_argument("--point-estimate", choices=("median", "mode"), default="median",
                        help="RUL point estimate the prognostic metrics score: the median "
                             "(default) or the most probable RUL, the paper's")
    parser.add_argument("--noise-free-features", action="store_true",
                        help="error budget: from a fault's onset the prognosis of the faulty "
                             "actuator sees its mode's own feature without noise, h(true "
                             "severity); detection and classification see the real features; "
                             "latest.json is left alone")
    return parser


def load_model(args: argparse.Namespace, settings: Settings
               ) -> tuple[PhmModel, dict[str, Any]]:
    """The model to evaluate and a description of where it came from."""
    if args.model_json:
        path = Path(args.model_json)
        doc = json.loads(path.read_text())
        return read_model_document(doc), {"source": f"file {path.resolve()}",
                                           **_training_info(doc.get("training"))}
    if args.design:
        from server.campaigns import campaign_store, train_from_directory

        t0 = time.perf_counter()
        model, report = train_from_directory(args.design, seed=args.seed, jobs=args.jobs)
        return model, {"source": f"trained on {campaign_store(args.design)} (seed {args.seed})",
                       "training_s": time.perf_counter() - t0, **_training_info(report)}
    return _model_from_db(settings, args.model_id)


def _training_info(report: Any) -> dict[str, Any]:
    """What the evaluation keeps of a training report (one beside a model file, as the demo's
    and the protocol's model documents carry, or one just made): the classifier's accuracy on
    its held-out design part and the measurement fits."""
    if not isinstance(report, dict):
        return {}
    clf = report.get("classifier") or {}
    detector = report.get("detector") or {}
    return {"classifier_accuracy": clf.get("accuracy"), "measurement": report.get("measurement"),
            "design_false_alarms": detector.get("design_false_alarms")}


def _model_from_db(settings: Settings, model_id: int | None) -> tuple[PhmModel, dict[str, Any]]:
    from server.db import make_engine, make_session_factory
    from server.errors import NotFound
    from server.services import models as model_service
    from server.vocabulary import ModelVersionStatus

    if settings.is_sqlite and not settings.sqlite_file.exists() \
            and not settings.database_url:
        raise ValueError(f"no database under {settings.data_dir}: pass --design, --model-json "
                         "or set HMSM_DATA_DIR / HMSM_DATABASE_URL")
    engine = make_engine(settings.effective_database_url)
    try:
        with make_session_factory(engine)() as session:
            if model_id is None:
                row = model_service.active_version(session=session)
                if row is None:
                    raise ValueError("no active model version: pass --design or --model-json, "
                                     "or train one with `hmsm train`")
            else:
                try:
                    row = model_service.get_version(session=session, version_id=model_id)
                except NotFound:
                    raise ValueError(f"model version {model_id} does not exist") from None
            if row.status != ModelVersionStatus.READY:
                raise ValueError(f"model version {row.id} is {row.status}")
            return read_model_document(row.payload), {
                "source": f"model version {row.id} ({row.name})", "model_id": row.id}
    finally:
        engine.dispose()


def write_outputs(result: dict[str, Any], out_dir: Path, *, latest: Path | None) -> list[Path]:
    """evaluation.json, summary.json, report.html, rul_<MODE>.html, summary.md; latest.json
    if asked."""
    from .report import markdown_tables, write_html_report, write_rul_pages
    from .summary import summary_document

    out_dir.mkdir(parents=True, exist_ok=True)
    js = out_dir / "evaluation.json"
    js.write_text(json.dumps(result, indent=1, allow_nan=False), encoding="utf-8")
    summary = out_dir / "summary.json"
    summary.write_text(json.dumps(_sanitise(summary_document(result)), indent=1,
                                  allow_nan=False) + "\n", encoding="utf-8")
    written = [js, summary, write_html_report(result, out_dir / "report.html")]
    written += write_rul_pages(result, out_dir)
    tables = markdown_tables(result)
    md = out_dir / "summary.md"
    md.write_text("\n\n".join(tables[k] for k in ("detection", "at_first_alarm",
                                                   "at_confirmation", "at_last_flight",
                                                   "prognosis", "prognosis_most_probable",
                                                   "timing") if k in tables)
                  + "\n", encoding="utf-8")
    written.append(md)
    if latest is not None:
        latest.parent.mkdir(parents=True, exist_ok=True)
        tmp = latest.with_suffix(".tmp")
        shutil.copyfile(js, tmp)
        tmp.replace(latest)
        written.append(latest)
    return written


def _sanitise(obj: Any) -> Any:
    """Non-finite floats to None (strict JSON)."""
    if isinstance(obj, float):
        return obj if obj == obj and obj not in (float("inf"), float("-inf")) else None
    if isinstance(obj, dict):
        return {str(k): _sanitise(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_sanitise(v) for v in obj]
    return obj


def run_evaluate(args: argparse.Namespace, settings: Settings, *,
                 progress: Callable[[int, int], None] | None = None) -> int:
    """Body of ``hmsm evaluate`` (see the module docstring); ``progress(done, total)`` is told
    of each pattern scored (the demo's background evaluation reports it to the dashboard),
    in place of the progress bar."""
    from server.campaigns import campaign_store, read_manifest

    from .false_alarms import against_design
    from .runner import evaluate_campaign

    campaign = campaign_store(args.campaign)  # a directory or s3://bucket/prefix
    if not campaign.exists("manifest.json"):
        raise ValueError(f"{campaign}: no manifest.json (not a campaign directory)")
    model, source = load_model(args, settings)
    stamp = dt.datetime.now(dt.UTC).strftime("%Y%m%dT%H%M%SZ")
    out_dir = Path(args.out) if args.out else settings.data_dir / "evaluation" / stamp
    if read_manifest(campaign).get("kind") == "concurrent":
        return _run_concurrent(args, model, source, campaign, out_dir)
    bar = None
    if progress is None and not args.no_progress:
        from tqdm import tqdm

        bar = tqdm(total=None, unit="pattern", desc="evaluate", file=sys.stderr)

        def show(done: int, total: int) -> None:
            bar.total = total
            bar.n = done
            bar.refresh()

        progress = show

    t0 = time.perf_counter()
    try:
        result = evaluate_campaign(model, campaign, jobs=max(int(args.jobs), 1),
                                   progress=progress, timing_flights=args.timing_flights,
                                   point_estimate=args.point_estimate,
                                   noise_free=args.noise_free_features)
    finally:
        if bar is not None:
            bar.close()
    measured = source.pop("design_false_alarms", None)  # kept once: beside the verification's
    result["model"] = {**(result.get("model") or {}), **source}
    detection = result["detection"]
    detection["per_unit_flight"] = against_design(detection["per_unit_flight"], measured)
    result["created_at"] = dt.datetime.now(dt.UTC).isoformat(timespec="seconds")
    result["wall_s"] = time.perf_counter() - t0
    result = _sanitise(result)
    # a noise-free error budget is no evaluation of the system: the dashboard keeps the last one
    latest = (None if args.no_latest or args.noise_free_features
              else settings.data_dir / "evaluation" / "latest.json")
    written = write_outputs(result, out_dir, latest=latest)
    _print_summary(result)
    for p in written:
        print(f"wrote {p}")
    return 0


def _run_concurrent(args: argparse.Namespace, model: PhmModel, source: dict[str, Any],
                    campaign: Any, out_dir: Path) -> int:
    """``hmsm evaluate`` on a concurrent campaign: concurrent.json and concurrent.md."""
    from .concurrent import concurrent_markdown, evaluate_concurrent

    if args.noise_free_features:
        raise ValueError("--noise-free-features is a single-fault error budget: a concurrent "
                         "campaign has no one fault's severity to read")
    t0 = time.perf_counter()
    result = evaluate_concurrent(model, campaign, jobs=max(int(args.jobs), 1))
    result["model"] = {**result["model"], **source}
    result["created_at"] = dt.datetime.now(dt.UTC).isoformat(timespec="seconds")
    result["wall_s"] = time.perf_counter() - t0
    out_dir.mkdir(parents=True, exist_ok=True)
    js, md = out_dir / "concurrent.json", out_dir / "concurrent.md"
    js.write_text(json.dumps(_sanitise(result), indent=1, allow_nan=False), encoding="utf-8")
    table = concurrent_markdown(result["summary"])
    md.write_text(table + "\n", encoding="utf-8")
    print(table)
    for p in (js, md):
        print(f"wrote {p}")
    return 0


def _print_summary(result: dict[str, Any]) -> None:
    from .report import markdown_tables

    t = markdown_tables(result)
    print(t["detection"])
    print()
    print(t["at_first_alarm"])
    print()
    if "at_confirmation" in t:
        print(t["at_confirmation"])
        print()
    print(t["at_last_flight"])
    print()
    print(t["prognosis"])
    print()
    print(t["prognosis_most_probable"])
    print()
    print(t["timing"])


def main_evaluate(argv: Sequence[str] | None = None) -> int:
    """Stand-alone entry point (``python -m server.evaluation.cli ...``)."""
    parser = add_evaluate_arguments(argparse.ArgumentParser(
        prog="hmsm evaluate", description=(__doc__ or "").split("\n")[0]))
    args = parser.parse_args(argv)
    try:
        return run_evaluate(args, load_settings())
    except ValueError as exc:
        print(f"hmsm evaluate: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main_evaluate())
