"""``sim-worker`` console script: subcommands of the simulated half-wing.

``sim-worker campaign --kind design|verification --out DIR --seed N --scale quick|paper``
writes a campaign of flight logs and its manifest (see :mod:`sim_worker.campaign`).
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence

__all__ = ["main", "build_parser"]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="sim-worker",
                                     description="Simulated half-wing of the EMA HMSM.")
    sub = parser.add_subparsers(dest="command", required=True)
    camp = sub.add_parser("campaign", help="write a design or verification campaign")
    camp.add_argument("--kind", choices=("design", "verification"), required=True)
    camp.add_argument("--out", required=True, help="output directory")
    camp.add_argument("--seed", type=int, default=0, help="campaign seed")
    camp.add_argument("--scale", choices=("quick", "paper"), default="quick")
    camp.add_argument("--workers", type=int, default=None,
                      help="worker processes (default: all cores); results do not depend on it")
    camp.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    camp.set_defaults(func=_cmd_campaign)
    return parser


def _cmd_campaign(args: argparse.Namespace) -> int:
    from .campaign import run_campaign

    t0 = time.perf_counter()
    manifest = run_campaign(args.kind, args.out, seed=args.seed, scale=args.scale,
                            workers=args.workers, progress=not args.no_progress)
    n = sum(len(p["flights"]) for p in manifest["patterns"])
    print(f"{args.kind} campaign: {len(manifest['patterns'])} patterns, {n} flights written to "
          f"{args.out} in {time.perf_counter() - t0:.1f} s")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    return int(args.func(args))


if __name__ == "__main__":
    sys.exit(main())
