"""One-command RUL plot of one fault mode (issue 6): RUL median and 5-95 % band against the
true RUL over the life of the mode's patterns of a campaign, the chain run as the service runs it.

Usage::

    python -m server.evaluation.rul_plot --campaign DIR (--model-json FILE | --design DIR)
        --mode MTWEAR --out file.html [--pattern ID]

The HTML file is self-contained (plotly.js embedded from the installed package, no CDN).
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path

from server.campaigns import load_campaign
from server.phm.chain import read_model_document
from server.vocabulary import PROGRESSIVE

from .report import rul_band_figure
from .runner import run_pattern
from .scoring import pattern_prognosis

__all__ = ["main"]


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=(__doc__ or "").split("\n")[0])
    ap.add_argument("--campaign", required=True, help="campaign directory")
    src = ap.add_mutually_exclusive_group(required=True)
    src.add_argument("--model-json", help="model JSON (ema-phm-model/5)")
    src.add_argument("--design", help="train on this design campaign first (seed 0)")
    ap.add_argument("--mode", required=True, choices=PROGRESSIVE)
    ap.add_argument("--pattern", help="only this pattern id (default: all of the mode)")
    ap.add_argument("--out", required=True, help="HTML file to write")
    args = ap.parse_args(argv)
    if args.model_json:
        doc = json.loads(Path(args.model_json).read_text())
        model = read_model_document(doc)
    else:
        from server.campaigns import train_from_directory

        model, _ = train_from_directory(args.design, seed=0)
    campaign = load_campaign(args.campaign)
    pats = [p for p in campaign.patterns if p.mode == args.mode
            and (args.pattern is None or p.id == args.pattern)]
    if not pats:
        print(f"no {args.mode} pattern in {args.campaign}", file=sys.stderr)
        return 2
    traces = [run_pattern(model, p) for p in pats]
    fig = rul_band_figure(traces, args.mode)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.write_html(out, include_plotlyjs=True, full_html=True)
    for t in traces:
        p = pattern_prognosis(t)
        ra = "-" if p["ra"] is None else f"{100 * p['ra']:.1f} %"
        print(f"{t['id']}: detected at flight {p['detected_index']} of {p['t_eol']:.0f}, "
              f"PH {p['ph']:.2f}, RA {ra}")
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
