"""The RUL speed-group suite: verification campaigns of unseen aircraft whose faults fail at
every speed the test station accepts, streamed once (features kept), scored per model in
minutes.

    python bench/rul_suite.py stream --root /work/campaigns/suite --per-mode 10 --workers 2
    python bench/rul_suite.py score --root /work/campaigns/suite --model MODEL.json \\
        --in-range /work/campaigns/prot/verification --out docs/results/rul_suite.json
    python bench/rul_suite.py calibration-stream --root /work/campaigns/cal --per-mode 20
    python bench/rul_suite.py calibrate --root /work/campaigns/cal --model UNCALIBRATED.json \\
        --out CALIBRATED.json

Each group is a quick-scale verification campaign (60 s recordings, as the demo flies), every
flight rendered, ``--per-mode`` patterns per fault mode, its own seed (none of them a design
seed), the expected fault-to-failure spans drawn uniformly from the group's range:

=============  ======  ==============  ==================================================
group          seed    spans [flights] what it stands for
=============  ======  ==============  ==================================================
very fast      31      30-60           the envelope's fast edge
fast           32      50-150          faster than the paper's protocol
slow           33      400-1000        slower than it
station        34      40-200          the spans a test-station operator asks for
station 60     35      60              the demo's 60-flight injections
=============  ======  ==============  ==================================================

The paper's protocol in range (25 patterns per mode, 170-360 flights, 120 s recordings) is
the ``hmsm protocol`` run's verification campaign, given with ``--in-range``. The station
groups are campaigns with the station's spans, not steered to an exact failure flight as a
live injection is (``bench/station_rul.py`` flies those, without keeping features).

The calibration layer of a model with a bank of rate hypotheses is conditional on the mode,
the leading hypothesis and whether the lead is confident, so it wants design runs in every
band: ``calibration-stream`` flies one quick-scale design campaign per band (seeds 4, 5 and 6,
none of them the training seed, spans log-uniform over 30-100, 100-300 and 300-1000 flights
as the bank's moments assume; the fast band every flight, as the service judges, the slower
two every third, where a life still gives a hundred flights and more) and ``calibrate``
replays them with the uncalibrated model and runs ``hmsm calibrate`` on all three.

The calibration designs are also the choice sets of the bank's settings (design seeds, not
the training seed): ``score --groups "cal fast,cal medium,cal slow"`` scores a model on them
uncalibrated, with the evaluations ``calibrate`` reuses. A choice between calibration
variants is scored on two more designs, every flight (``calibration-stream --groups "choice
fast,choice medium"``: seeds 7 and 8, 30-100 and 100-300 flights).

``score`` runs ``hmsm evaluate`` with ``--model`` on every streamed group (its evaluation kept
under ``ROOT/scores/<model stem>/``, reused when present) and prints and writes the group x
mode table of :mod:`rul_speed_groups` (coverage, truth below the band, widths, PH, RA).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from rul_speed_groups import group_figures, markdown  # noqa: E402


@dataclass(frozen=True)
class Group:
    """A campaign of the suite: its seed and spans, the kind of run it flies, the cadence of
    its rendered flights and how its spans are drawn."""

    name: str
    seed: int
    spans: tuple[float, float]
    kind: str = "verification"
    render_every: int = 1
    span_draw: str = "uniform"

    @property
    def slug(self) -> str:
        return self.name.replace(" ", "-")


GROUPS = (Group("very fast", 31, (30.0, 60.0)), Group("fast", 32, (50.0, 150.0)),
          Group("slow", 33, (400.0, 1000.0)), Group("station", 34, (40.0, 200.0)),
          Group("station 60", 35, (60.0, 60.0)))
#: the calibration designs, one per band of the bank (``TrainingConfig.rate_band_edges``)
CALIBRATION = (Group("cal fast", 4, (30.0, 100.0), "design", 1, "log"),
               Group("cal medium", 5, (100.0, 300.0), "design", 3, "log"),
               Group("cal slow", 6, (300.0, 1000.0), "design", 3, "log"))
#: design campaigns kept apart from the calibration designs, on which a choice between
#: calibration variants is scored (every flight, as the service judges)
CHOICE = (Group("choice fast", 7, (30.0, 100.0), "design", 1, "log"),
          Group("choice medium", 8, (100.0, 300.0), "design", 1, "log"))


def _chosen(names: str | None, among: tuple[Group, ...] = GROUPS) -> list[Group]:
    if not names:
        return list(GROUPS)
    wanted = [n.strip() for n in names.split(",")]
    known = {g.name: g for g in among}
    unknown = [n for n in wanted if n not in known]
    if unknown:
        raise SystemExit(f"unknown groups {unknown}; known: {sorted(known)}")
    return [known[n] for n in wanted]


def stream(root: Path, groups: list[Group], per_mode: int, workers: int) -> None:
    """Each group's campaign under ``root/<slug>`` (resumed where a run stopped)."""
    for g in groups:
        lo, hi = g.spans
        # features kept, a flight log only now and then (a whole group's logs are tens of GB)
        cmd = ["hmsm", "campaign", "--kind", g.kind, "--scale", "quick",
               "--seed", str(g.seed), "--span-range", f"{lo:g},{hi:g}",
               "--render-every", str(g.render_every), "--span-draw", g.span_draw,
               "--patterns-per-mode", str(per_mode), "--workers", str(workers),
               "--no-progress", "--out", str(root / g.slug)]
        print(f"[{g.name}] {' '.join(cmd)}", flush=True)
        subprocess.run(cmd, check=True)


def _evaluated(campaign: Path, model: Path, out: Path, jobs: int) -> Path:
    """``hmsm evaluate`` of ``model`` on ``campaign`` into ``out`` (kept and reused)."""
    if not (out / "summary.json").exists():
        subprocess.run(["hmsm", "evaluate", "--campaign", str(campaign), "--model-json",
                        str(model), "--out", str(out), "--jobs", str(jobs), "--no-latest",
                        "--no-progress", "--timing-flights", "0"], check=True)
    return out


def score(root: Path, groups: list[Group], model: Path, in_range: Path | None, jobs: int
          ) -> dict[str, dict]:
    """The group x mode figures of ``model`` on every streamed group."""
    out_root = root / "scores" / model.stem
    targets = [(g.name, root / g.slug) for g in groups if (root / g.slug).exists()]
    if in_range is not None:
        targets.insert(0, ("in range", in_range))
    return {name: group_figures(_evaluated(campaign, model, out_root / name.replace(" ", "-"),
                                           jobs))
            for name, campaign in targets}


def calibrate(root: Path, model: Path, out: Path, jobs: int, weight_split: float | None = None
              ) -> None:
    """The uncalibrated ``model`` replayed on every calibration design, then calibrated."""
    evals = [_evaluated(root / g.slug, model, root / "scores" / model.stem / g.slug, jobs)
             for g in CALIBRATION]
    cmd = ["hmsm", "calibrate", "--model-json", str(model), "--out", str(out)]
    for e in evals:
        cmd += ["--evaluation", str(e)]
    if weight_split is not None:
        cmd += ["--weight-split", f"{weight_split:g}"]
    subprocess.run(cmd, check=True)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="command", required=True)
    s = sub.add_parser("stream", help="stream the groups' campaigns")
    s.add_argument("--root", type=Path, required=True)
    s.add_argument("--groups", default=None, help="comma-separated group names (default all)")
    s.add_argument("--per-mode", type=int, default=10)
    s.add_argument("--workers", type=int, default=2)
    c = sub.add_parser("score", help="score a model on the streamed groups")
    c.add_argument("--root", type=Path, required=True)
    c.add_argument("--groups", default=None, help="comma-separated group names (default the "
                   "verification groups; the calibration designs' names score a choice set)")
    c.add_argument("--model", type=Path, required=True)
    c.add_argument("--in-range", type=Path, default=None,
                   help="the protocol run's verification campaign (the in-range group)")
    c.add_argument("--jobs", type=int, default=2)
    c.add_argument("--out", type=Path, default=None, help="JSON file to write")
    cs = sub.add_parser("calibration-stream", help="stream the calibration designs, one per "
                        "band of the bank")
    cs.add_argument("--root", type=Path, required=True)
    cs.add_argument("--groups", default=None, help="comma-separated design names (default "
                    "the calibration designs; 'choice fast,choice medium' stream the choice sets)")
    cs.add_argument("--per-mode", type=int, default=20)
    cs.add_argument("--workers", type=int, default=2)
    cb = sub.add_parser("calibrate", help="replay the calibration designs and calibrate")
    cb.add_argument("--root", type=Path, required=True)
    cb.add_argument("--model", type=Path, required=True, help="the uncalibrated model")
    cb.add_argument("--out", type=Path, required=True, help="the calibrated model to write")
    cb.add_argument("--jobs", type=int, default=2)
    cb.add_argument("--weight-split", type=float, default=None,
                    help="hmsm calibrate's --weight-split (default: its own)")
    args = ap.parse_args(argv)
    if args.command in ("stream", "calibration-stream") and args.per_mode < 1:
        ap.error("--per-mode must be at least 1")
    if args.command == "calibration-stream":
        stream(args.root, _chosen(args.groups, CALIBRATION + CHOICE) if args.groups
               else list(CALIBRATION), args.per_mode, args.workers)
        return 0
    if args.command == "calibrate":
        calibrate(args.root, args.model, args.out, args.jobs, args.weight_split)
        return 0
    if args.command == "stream":
        stream(args.root, _chosen(args.groups), args.per_mode, args.workers)
        return 0
    groups = _chosen(args.groups, GROUPS + CALIBRATION + CHOICE)
    figures = score(args.root, groups, args.model, args.in_range, args.jobs)
    print(markdown(figures))
    if args.out:
        args.out.write_text(json.dumps({"model": str(args.model), "groups": figures},
                                       indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
