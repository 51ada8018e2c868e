"""``sim-worker`` console script: subcommands of the simulated half-wing.

``sim-worker campaign --kind design|verification|concurrent --out DIR --seed N --scale SCALE``
writes a campaign of flight logs and its manifest (see :mod:`sim_worker.campaign`), to a
directory or to ``s3://bucket/prefix`` (credentials from the AWS_* environment variables, a
store other than AWS S3 at ``HMSM_S3_ENDPOINT_URL``);
``hmsm campaign`` takes the same options and streams it (features kept, logs sampled).
``sim-worker span-check --out FILE`` measures how well the test station honours a requested
time to failure (:mod:`.span_check`).
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
import time
from collections.abc import Iterator, Sequence
from concurrent.futures import Executor
from typing import Any

__all__ = ["main", "build_parser", "add_campaign_arguments", "campaign_executor",
           "parse_span_range", "run_campaign_command"]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="sim-worker",
                                     description="Simulated half-wing of the EMA HMSM.")
    sub = parser.add_subparsers(dest="command", required=True)
    camp = sub.add_parser("campaign", help="write a design, verification or concurrent-fault "
                          "campaign")
    add_campaign_arguments(camp)
    camp.set_defaults(func=_cmd_campaign)


    check = sub.add_parser("span-check", help="fly test-station injections to failure and "
                           "measure how well the requested time to failure is honoured")
    check.add_argument("--out", required=True, help="JSON report to write")
    check.add_argument("--per-mode", type=int, default=20, help="injections per progressive mode")
    check.add_argument("--span-range", default="40,200", metavar="LOW,HIGH",
                       help="requested times to failure, drawn uniformly [flights]")
    check.add_argument("--duration", type=float, default=60.0,
                       help="seconds recorded per flight (the demo's sim worker: 60)")
    check.add_argument("--seed", type=int, default=0)
    check.add_argument("--workers", type=int, default=1)
    check.add_argument("--fixed-rate", action="store_true",
                       help="no steering: the rate fixed at onset, for comparison")
    check.set_defaults(func=_cmd_span_check)

    run = sub.add_parser("run", help="fly the simulated fleet against a running HMSM")
    run.add_argument("--api", required=True, help="HMSM base URL, e.g. http://127.0.0.1:8000")
    run.add_argument("--key", default=os.environ.get("HMSM_SIM_KEY"),
                     required="HMSM_SIM_KEY" not in os.environ,
                     help="API key that may upload (and register missing aircraft: admin); "
                     "default $HMSM_SIM_KEY, which keeps it off the process list")
    run.add_argument("--operator-key", default=os.environ.get("HMSM_SIM_OPERATOR_KEY"),
                     help="key for test-station reports (default $HMSM_SIM_OPERATOR_KEY, "
                     "else --key)")
    run.add_argument("--aircraft", type=int, default=10, help="number of simulated aircraft")
    run.add_argument("--rate", type=float, default=20.0, help="flights per minute, whole fleet")
    run.add_argument("--seed", type=int, default=0)
    run.add_argument("--duration", type=float, default=120.0,
                     help="seconds of actuator activity recorded per flight")
    run.add_argument("--max-flights", type=int, default=None, help="stop after this many")
    run.set_defaults(func=_cmd_run)
    return parser


def _cmd_run(args: argparse.Namespace) -> int:
    import logging
    import signal
    import threading

    from .service import Api, ApiError, SimFleetRunner

    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s %(message)s")
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    api = Api(args.api, args.key, operator_key=args.operator_key, stop=stop.is_set)
    runner = SimFleetRunner(api, n_aircraft=args.aircraft, rate_per_min=args.rate,
                            seed=args.seed, duration_s=args.duration, sleep=stop.wait)
    try:
        flown = runner.run(max_flights=args.max_flights, stop=stop.is_set)
    except ApiError as exc:
        print(f"sim-worker: the HMSM refused a request: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130
    finally:
        api.close()
    print(f"sim-worker: {flown} flights flown")
    return 0


def add_campaign_arguments(camp: argparse.ArgumentParser) -> argparse.ArgumentParser:
    """The options of a campaign run (``sim-worker campaign`` and ``hmsm campaign``)."""
    from .campaign import KINDS, SCALES

    camp.add_argument("--kind", choices=KINDS, required=True,
                      help="design, verification, or concurrent (two faults at once per "
                      "pattern: scales ci and quick)")
    camp.add_argument("--out", required=True, help="output directory, or s3://bucket/prefix "
                      "(AWS_* credentials; endpoint $HMSM_S3_ENDPOINT_URL); run again with the "
                      "same options to resume an interrupted campaign")
    camp.add_argument("--seed", type=int, default=0, help="campaign seed")
    camp.add_argument("--scale", choices=tuple(SCALES), default="quick",
                      help="quick (CI figures), paper (sparse rendering, quick looks), "
                      "protocol (the paper's: every flight of 25 patterns per mode), "
                      "ci (the protocol reduced for the test suite), shipped (the shipped "
                      "model's design: long healthy cycles at mixed recording lengths and "
                      "test-station conditions)")
    camp.add_argument("--workers", type=int, default=None,
                      help="local worker processes (default: all cores); results do not "
                      "depend on it")
    camp.add_argument("--dask", default=None, metavar="ADDRESS",
                      help="run the patterns on a Dask distributed scheduler "
                      "(e.g. tcp://host:8786) instead of local processes; its workers need "
                      "this package and write kept flight logs under --out: with --out "
                      "s3://... they share no directory")
    camp.add_argument("--render-every", type=int, default=None,
                      help="render every k-th flight of a fault-to-failure run, k odd (default: "
                      "the scale's; 1 renders every flight, as a fleet in service downloads "
                      "them)")
    camp.add_argument("--span-range", default=None, metavar="LOW,HIGH",
                      help="range of the expected fault-to-failure span drawn per pattern "
                      "[flights] (default: the scale's; designs 30,1000, the test station's "
                      "envelope; verifications 170,360)")
    camp.add_argument("--span-draw", choices=("uniform", "log"), default=None,
                      help="how a pattern draws its span from the range: uniformly, or "
                      "log-uniformly (default: the scale's; log for designs)")
    camp.add_argument("--per-mode", type=int, default=None, metavar="N",
                      help="fly every healthy pattern but only the first N patterns of each "
                      "fault mode (0: the healthy ones alone; concurrent: of each combination "
                      "kind), the same flights as in the whole campaign")
    camp.add_argument("--patterns-per-mode", type=int, default=None, metavar="N",
                      help="plan N fault patterns per mode instead of the scale's (a campaign "
                      "of its own: its patterns are seeded differently); --per-mode then "
                      "flies the first of them")
    camp.add_argument("--step-flights", type=int, default=None, metavar="N",
                      help="fly each step fault's (SE, BDO) pattern for N flights instead of "
                      "the scale's (onset where the scale puts it; the first flights are the "
                      "same): how many flights a step fault takes to be found")
    camp.add_argument("--recordings", default=None, metavar="S[,S...]",
                      help="recording lengths [s] every rendered flight draws its own from, "
                      "e.g. 120 (every flight 120 s) or 60,90,120,180,240,300 (a fleet mixing "
                      "them); default: the scale's")
    camp.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    camp.add_argument("--bases", default=None, help="robustness: comma-separated bases to fly "
                      "from (Turin, Vancouver, Abu Dhabi) instead of the 4/3/3 mix")
    camp.add_argument("--noise-scale", type=float, default=1.0,
                      help="robustness: multiply every sensor's noise by this factor")
    camp.add_argument("--sensor-fault", action=_SensorFaultAction, default=[], metavar="SPEC",
                      help="sensor health: degrade one sensor of one actuator on every "
                      "aircraft, POSITION.SENSOR:noise=FACTOR (noise x FACTOR) or "
                      "POSITION.lvdt:drift=METRES (LVDT offset + METRES per flight); "
                      "repeatable, e.g. WT.lvdt:noise=2")
    return camp


class _SensorFaultAction(argparse.Action):
    """Appends a parsed :class:`~sim_worker.campaign.SensorFault`; a bad or repeated spec is
    an argparse error (usage and message) before any simulation starts."""

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace,
                 values: Any, option_string: str | None = None) -> None:
        from .campaign import SensorFault

        try:
            fault = SensorFault.parse(str(values))
        except ValueError as exc:
            raise argparse.ArgumentError(self, str(exc)) from None
        given = list(getattr(namespace, self.dest, None) or [])  # never the shared default
        if any((f.position, f.sensor, f.kind) == (fault.position, fault.sensor, fault.kind)
               for f in given):
            raise argparse.ArgumentError(
                self, f"{fault.position}.{fault.sensor}:{fault.kind} given twice")
        setattr(namespace, self.dest, [*given, fault])


def parse_span_range(text: str | None) -> tuple[float, float] | None:
    if text is None:
        return None
    parts = text.split(",")
    try:
        lo, hi = (float(p) for p in parts)
    except ValueError:
        raise ValueError(f"--span-range takes LOW,HIGH in flights, got {text!r}") from None
    return lo, hi


@contextlib.contextmanager
def campaign_executor(address: str | None) -> Iterator[Executor | None]:
    """A Dask distributed client's executor for ``address``, or None (local processes)."""
    if address is None:
        yield None
        return
    try:
        from distributed import Client
    except ImportError:
        raise ValueError("--dask needs the 'distributed' package "
                         "(pip install 'ema-hmsm[cluster]')") from None
    with Client(address, timeout=30) as client:
        yield client.get_executor()


def run_campaign_command(args: argparse.Namespace, sink: object | None = None,
                         endpoint: str | None = None) -> dict[str, Any]:
    """Run the campaign an argument namespace of :func:`add_campaign_arguments` describes;
    ``endpoint``: the S3 server of an ``s3://`` --out (None: AWS S3)."""
    from server.campaign_store import CampaignStore

    from .campaign import run_campaign

    out = CampaignStore.at(args.out, endpoint)
    out.check()  # a malformed URL or a missing bucket fails before any simulation
    bases = tuple(b.strip() for b in args.bases.split(",")) if args.bases else None
    with campaign_executor(args.dask) as executor:
        return run_campaign(args.kind, out, seed=args.seed, scale=args.scale,
                            workers=args.workers, progress=not args.no_progress, bases=bases,
                            noise_scale=args.noise_scale,
                            sensor_faults=tuple(args.sensor_fault or ()),
                            render_every=args.render_every,
                            span_flights=parse_span_range(args.span_range),
                            span_draw=args.span_draw,
                            sink=sink, executor=executor,  # type: ignore[arg-type]
                            per_mode=args.per_mode,
                            recordings_s=parse_recordings(args.recordings),
                            patterns_per_mode=args.patterns_per_mode,
                            step_flights=args.step_flights)


def parse_recordings(text: str | None) -> tuple[float, ...] | None:
    if text is None:
        return None
    try:
        return tuple(float(p) for p in text.split(","))
    except ValueError:
        raise ValueError(f"--recordings takes seconds separated by commas, got {text!r}") \
            from None


def _cmd_campaign(args: argparse.Namespace) -> int:
    from server.campaign_store import ENDPOINT_ENV

    t0 = time.perf_counter()
    manifest = run_campaign_command(args, endpoint=os.environ.get(ENDPOINT_ENV))
    n = sum(len(p["flights"]) for p in manifest["patterns"])
    print(f"{args.kind} campaign: {len(manifest['patterns'])} patterns, {n} flights written to "
          f"{args.out} in {time.perf_counter() - t0:.1f} s")
    return 0


def _cmd_span_check(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from .span_check import check_spans, span_cases, summarise, write_report

    lo, hi = parse_span_range(args.span_range) or (40.0, 200.0)
    if args.per_mode < 1 or lo < 10:
        raise ValueError("need --per-mode >= 1 and spans of at least 10 flights")
    cases = span_cases(args.per_mode, args.seed, (int(lo), int(hi)))
    t0 = time.perf_counter()
    records = list(tqdm(check_spans(cases, seed=args.seed, duration_s=args.duration,
                                    steered=not args.fixed_rate, workers=args.workers),
                        total=len(cases), desc="injections", unit="inj"))
    settings = {"per_mode": args.per_mode, "span_range": [int(lo), int(hi)],
                "duration_s": args.duration, "seed": args.seed,
                "steered": not args.fixed_rate, "elapsed_s": round(time.perf_counter() - t0)}
    write_report(args.out, records, settings)
    for mode, row in summarise(records).items():
        print(f"{mode:7s} {row['injections']:3d} injections: {100 * row['within_10pct']:5.1f} % "
              f"within 10 %, mean error {100 * (row['mean_error'] or 0):+6.1f} %, largest "
              f"{100 * (row['max_abs_error'] or 0):5.1f} %, {row['not_failed']} not failed")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args))
    except ValueError as exc:
        print(f"sim-worker: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
