"""``hmsm protocol``: the paper's assessment (sections 4.3 and 5) from nothing, in one command.

Streams a design campaign and a verification campaign on unseen aircraft (every flight of
every pattern simulated, features kept, logs sampled), trains the chain on the design one and
evaluates it on the verification one::

    OUT/design/          streamed design campaign (seed --design-seed)
    OUT/model.json       the model trained on it (training seed 0) as soon as it is complete,
                         with its training report
    OUT/verification/    streamed verification campaign (seed --verification-seed)
    OUT/evaluation/      hmsm evaluate's outputs: summary.json, evaluation.json, report.html

Each step resumes where an interrupted run stopped (a finished pattern is never simulated
again, a finished campaign never regenerated, a trained model never retrained).
``--model-json FILE`` takes a model such a run trained (its ``model.json``) instead of the
design campaign and the training: the verification alone, the longer two thirds of the run.
``--scale ci`` runs the same machinery reduced (a few patterns per mode, short recordings,
fast faults) in a few minutes.

``--score-finished`` scores a verification campaign still running (or interrupted) on the
patterns it has finished, once the design campaign is complete: they are copied out as a
campaign of their own (``OUT/partial/verification``, its manifest saying how many of how many)
and evaluated into ``OUT/partial/evaluation``; the run itself goes on untouched. Patterns are
simulated round by round over the modes, so a part holds about the same share of each.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path
from typing import TYPE_CHECKING

from server.config import Settings

if TYPE_CHECKING:  # pragma: no cover - typing only
    from server.campaigns import FeatureSink

__all__ = ["MODEL_FILE", "MODEL_FORMAT", "add_protocol_arguments", "run_protocol"]

MODEL_FILE = "model.json"
MODEL_FORMAT = "ema-protocol-model/1"
TRAINING_SEED = 0  # the seed of the design's 70/30 split


def add_protocol_arguments(parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
    parser.add_argument("--out", required=True, help="root directory of the run; run again "
                        "with the same options to resume")
    parser.add_argument("--scale", choices=("protocol", "ci"), default="protocol",
                        help="protocol: the paper's (default); ci: reduced, a few minutes")
    parser.add_argument("--design-seed", type=int, default=1)
    parser.add_argument("--verification-seed", type=int, default=2)
    parser.add_argument("--span-range", default=None, metavar="LOW,HIGH",
                        help="verification only: range of fault-to-failure spans [flights] "
                        "(faults faster or slower than design's)")
    parser.add_argument("--per-mode", type=int, default=None, metavar="N",
                        help="a reduced protocol: every healthy cycle but only the first N "
                        "patterns of each fault mode, in both campaigns (the same flights as "
                        "the whole run's)")
    parser.add_argument("--keep-raw-every", type=int, default=200, metavar="K",
                        help="keep the log of every K-th flight of a pattern (default 200)")
    parser.add_argument("--workers", type=int, default=None,
                        help="local worker processes (default: all cores)")
    parser.add_argument("--dask", default=None, metavar="ADDRESS",
                        help="simulate on a Dask distributed scheduler (tcp://host:8786)")
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bars")
    parser.add_argument("--model-json", default=None, metavar="FILE",
                        help="score with this model (a protocol run's model.json) instead of "
                        "streaming and training on a design campaign")
    parser.add_argument("--score-finished", action="store_true",
                        help="score the verification patterns finished so far (the design "
                        "campaign must be complete); the run is not touched")
    return parser


def _campaign_args(args: argparse.Namespace, kind: str, seed: int, out: Path,
                   span_range: str | None) -> argparse.Namespace:
    return argparse.Namespace(kind=kind, out=str(out), seed=seed, scale=args.scale,
                              workers=args.workers, dask=args.dask, render_every=None,
                              span_range=span_range, span_draw=None,
                              no_progress=args.no_progress, bases=None,
                              noise_scale=1.0, sensor_fault=None, per_mode=args.per_mode,
                              recordings=None, patterns_per_mode=None,
                              step_flights=None)


def _evaluate_args(args: argparse.Namespace, model: Path, campaign: Path, out: Path
                   ) -> argparse.Namespace:
    return argparse.Namespace(campaign=str(campaign), design=None,
                              model_json=str(model), model_id=None, seed=0, out=str(out),
                              jobs=args.workers or min(2, os.cpu_count() or 1),
                              timing_flights=6, no_latest=True, no_progress=args.no_progress,
                              point_estimate="median", noise_free_features=False)


def run_protocol(args: argparse.Namespace, settings: Settings) -> int:
    from server.campaigns import FeatureSink
    from sim_worker.cli import run_campaign_command

    from .cli import run_evaluate

    if args.out.startswith("s3:"):  # its model and reports are local files
        raise ValueError("hmsm protocol --out takes a local directory; stream the campaigns "
                         "to S3 with `hmsm campaign --out s3://...` and score them with "
                         "`hmsm train` / `hmsm evaluate --campaign s3://...`")
    root = Path(args.out)
    sink = FeatureSink(keep_raw_every=args.keep_raw_every)
    if args.model_json is not None:
        _check_model(Path(args.model_json))  # before hours of simulation, not after
    if args.score_finished:
        return _score_finished(args, settings, root, sink)
    t0 = time.perf_counter()
    kinds = [("verification", args.verification_seed, args.span_range)]
    if args.model_json is None:
        kinds.insert(0, ("design", args.design_seed, None))
    for kind, seed, span in kinds:
        manifest = run_campaign_command(_campaign_args(args, kind, seed, root / kind, span),
                                        sink=sink)
        n = sum(len(p["flights"]) for p in manifest["patterns"])
        print(f"{kind} campaign: {len(manifest['patterns'])} patterns, {n} flights "
              f"({time.perf_counter() - t0:.0f} s so far)", flush=True)
        if kind == "design":  # on disk before the verification's hours: usable at once
            _trained_model(args, root)
    code = run_evaluate(_evaluate_args(args, _model(args, root), root / "verification",
                                       root / "evaluation"), settings)
    print(f"protocol run finished in {time.perf_counter() - t0:.0f} s: "
          f"{root / 'evaluation' / 'summary.json'}")
    return code


def _check_model(path: Path) -> None:
    """ValueError, with the reason, unless ``path`` holds a model the chain reads."""
    from server.phm.chain import read_model_document

    try:
        read_model_document(json.loads(path.read_text()))
    except (OSError, ValueError, KeyError, TypeError, AttributeError) as exc:
        raise ValueError(f"--model-json {path}: not a model the chain reads ({exc})") from None


def _model(args: argparse.Namespace, root: Path) -> Path:
    """The model to score with: ``--model-json``, else the run's own (trained if not yet)."""
    return Path(args.model_json) if args.model_json is not None else _trained_model(args, root)


def _trained_model(args: argparse.Namespace, root: Path) -> Path:
    """``OUT/model.json``: the model trained on the complete design campaign, made
    once; written whole or not at all, so an interrupted training is simply redone."""
    from server.campaigns import train_from_directory
    from server.demo_model import trained_model_document

    path = root / MODEL_FILE
    if path.exists():
        return path
    t0 = time.perf_counter()
    model, report = train_from_directory(root / "design", seed=TRAINING_SEED, jobs=args.workers)
    design = {"kind": "design", "scale": args.scale, "seed": args.design_seed}
    doc = trained_model_document(MODEL_FORMAT, design, TRAINING_SEED, model.to_dict(), report)
    tmp = path.with_suffix(".part")
    tmp.write_text(json.dumps(doc, sort_keys=True, separators=(",", ":")) + "\n")
    tmp.replace(path)
    print(f"model trained on {root / 'design'} in {time.perf_counter() - t0:.0f} s: {path}",
          flush=True)
    return path


def _score_finished(args: argparse.Namespace, settings: Settings, root: Path,
                    sink: FeatureSink) -> int:
    from sim_worker.campaign import SETTINGS_FILE, snapshot_campaign

    from .cli import run_evaluate

    if args.model_json is None and not (root / "design" / SETTINGS_FILE).exists():
        raise ValueError(f"{root / 'design'}: the design campaign is not complete yet; "
                         "--score-finished needs it to train")
    if (root / "verification" / SETTINGS_FILE).exists():
        raise ValueError(f"{root / 'verification'} is complete: run `hmsm protocol --out "
                         f"{root}` to score all of it")
    part = root / "partial"
    manifest = snapshot_campaign(root / "verification", part / "verification", sink=sink)
    done, planned = manifest["partial"]["patterns"], manifest["partial"]["of"]
    if not done:
        raise ValueError(f"{root / 'verification'}: no pattern finished yet")
    print(f"scoring {done} of {planned} verification patterns", flush=True)
    return run_evaluate(_evaluate_args(args, _model(args, root), part / "verification",
                                       part / "evaluation"), settings)
