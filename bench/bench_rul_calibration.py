"""Calibration of the generic RUL engine (server.phm.prognosis.forecast) on synthetic families.

Run: ``python bench/bench_rul_calibration.py [--units-per-family 20] [--half tuning|held-out]
[--progpy] [--out PATH] [--guard-prefixes N ...]`` (from the repository root). Writes
``docs/results/rul_calibration_<half>.json`` unless ``--out`` names another file.
``--progpy`` scores progpy's particle filter with a linear-fade model on the same units beside
ours (progpy is the ``bench`` extra).

Families (none is the engine's own law by construction except where physics says so): linear,
exponential, power-law, change point then growth, capacity-like fade with recovery jumps,
noise growing with level, a knee (a slow linear phase, then an accelerating drop, as a cell's
capacity fades) and quiet then exponential (flat until a defect starts, as a bearing's
vibration). Every unit gets a random life (80-400 samples), time unit
(10^-2..10^2 per step), sampling (even or jittered steps), noise, and an indicator that rises
or falls toward its threshold. Draws with an even index are the tuning half (defaults are
chosen on it only), odd ones the held-out half. Each unit is scored at 8 instants from 40 %
to 95 % of its life, each prediction from its prefix only: coverage of the central 50 % and
90 % intervals, the PIT histogram (share of the distribution below the true RUL), relative
accuracy of the median (RA), its mean over a unit (CRA) and alpha-lambda (alpha 0.2, lambda
0.5, from 40 % of life), the median widths of both intervals relative to the true RUL, and
the online guard's widening (mean, and the share of forecasts it widened). The ``--guard-*``
options override the guard's settings (``--guard-prefixes 0``: no guard); choosing them:
tuning half only.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from server.phm.metrics import bootstrap_indices, bootstrap_mean_interval  # noqa: E402
from server.phm.prognosis.forecast import forecast_rul  # noqa: E402
from server.phm.prognosis.law_average import LawAverageConfig  # noqa: E402

FAMILIES = ("linear", "exponential", "power", "change_point", "capacity_jumps", "growing_noise",
            "knee", "quiet_then_exponential")


def _truth(family: str, u: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Noise-free severity at life fractions u (1.0 at u = 1)."""
    if family == "linear":
        return u.copy()
    if family in ("exponential", "growing_noise"):
        k = rng.uniform(1.0, 4.0)
        return np.expm1(k * u) / math.expm1(k)
    if family == "power":
        return u ** rng.uniform(1.3, 3.0)
    if family == "change_point":
        c, p = rng.uniform(0.2, 0.5), rng.uniform(1.0, 2.0)
        return np.clip((u - c) / (1.0 - c), 0.0, None) ** p
    if family == "capacity_jumps":
        # fade slightly convex, with recovery jumps that decay back over about 3 % of life
        s = u ** rng.uniform(1.0, 1.6)
        for start in rng.uniform(0.05, 0.85, rng.integers(2, 6)):
            s -= rng.uniform(0.02, 0.08) * np.where(u >= start, np.exp(-(u - start) / 0.03), 0.0)
        return s / s[-1]
    if family == "knee":
        # a cell's capacity fade: a slow linear phase, then past the knee an accelerating drop
        a, knee, p = rng.uniform(0.1, 0.3), rng.uniform(0.5, 0.8), rng.uniform(1.5, 3.0)
        return a * u + (1.0 - a) * (np.clip(u - knee, 0.0, None) / (1.0 - knee)) ** p
    if family == "quiet_then_exponential":
        # a bearing's vibration: flat until a defect starts, then growing exponentially
        start, k = rng.uniform(0.3, 0.7), rng.uniform(3.0, 6.0)
        return np.expm1(k * np.clip(u - start, 0.0, None) / (1.0 - start)) / math.expm1(k)
    raise ValueError(family)


def make_unit(family: str, draw: int) -> dict:
    rng = np.random.default_rng([FAMILIES.index(family), draw])
    life = int(rng.integers(80, 401))
    n = life + 1
    if rng.random() < 0.5:
        steps = np.ones(n - 1)
    else:
        steps = rng.uniform(0.3, 1.7, n - 1)
    idx = np.r_[0.0, np.cumsum(steps)]
    u = idx / idx[-1]
    sev = _truth(family, u, rng)
    sigma = rng.uniform(0.01, 0.05)
    noise_sd = sigma * (1.0 + 3.0 * np.clip(sev, 0, None)) if family == "growing_noise" \
        else np.full(n, sigma)
    measured = sev + noise_sd * rng.standard_normal(n)
    unit = 10.0 ** rng.uniform(-2.0, 2.0)
    baseline, scale = rng.uniform(-5, 5), rng.choice([-1.0, 1.0]) * 10.0 ** rng.uniform(-1, 1)
    cross = np.flatnonzero(sev >= 1.0 - 1e-9)
    eol = idx[cross[0]] * unit
    return {"family": family, "draw": draw, "time": idx * unit, "eol": float(eol),
            "series": baseline + scale * measured, "baseline": baseline,
            "threshold": baseline + scale}


CONFIG: LawAverageConfig | None = None
#: the online guard's settings the command line may override
GUARD_OPTIONS = {"guard_prefixes": int, "guard_horizon": float, "guard_window": float,
                 "guard_miss_rate": float, "guard_gain": float}


def ours(t: np.ndarray, x: np.ndarray, threshold: float, baseline: float
         ) -> tuple[np.ndarray, float]:
    """The RUL samples (the guard's widening applied) and the widening."""
    f = forecast_rul(x, threshold, time=t, rng=0, config=CONFIG)
    return f.samples, f.guard_widening


def scored_samples(unit: dict) -> list[int]:
    """Indices of the 8 scored instants, 40 % to 95 % of life."""
    return [int(np.searchsorted(unit["time"], f * unit["eol"], side="right")) - 1
            for f in np.linspace(0.4, 0.95, 8)]


def ours_at(unit: dict) -> list[tuple[np.ndarray, float]]:
    t, x = unit["time"], unit["series"]
    return [ours(t[:i + 1], x[:i + 1], unit["threshold"], unit["baseline"])
            for i in scored_samples(unit)]


def progpy_at(unit: dict) -> list[np.ndarray]:
    """progpy's particle filter, linear fade (bench/_progpy_linear.py), same instants and
    the same horizon rule as ours (20 spans of the prefix)."""
    from _progpy_linear import progpy_forecasts

    t, x = unit["time"], unit["series"]
    base = float(np.median(x[:5]))
    at = scored_samples(unit)
    out = progpy_forecasts(t, (x - base) / (unit["threshold"] - base), at,
                           20.0 * float(t[at[-1]] - t[0]))
    return [(samples, 0.0) for samples in out]


def _relative_width(lo: float, hi: float, true_rul: float) -> float | None:
    return float((hi - lo) / true_rul) if np.isfinite(hi) else None


def score_unit(unit: dict, forecasts: list[tuple[np.ndarray, float]]) -> list[dict]:
    t, eol = unit["time"], unit["eol"]
    rows = []
    for frac, i, (samples, widening) in zip(np.linspace(0.4, 0.95, 8), scored_samples(unit),
                                            forecasts, strict=True):
        true_rul = eol - t[i]
        q = np.quantile(samples, [0.05, 0.25, 0.5, 0.75, 0.95], method="inverted_cdf")
        rows.append({"frac": float(frac), "true": true_rul,
                     "in50": bool(q[1] <= true_rul <= q[3]),
                     "in90": bool(q[0] <= true_rul <= q[4]),
                     "pit": float(np.mean(samples <= true_rul)),
                     # RA floored at 0: a median beyond the horizon scores as one twice the truth
                     "ra": float(max(1.0 - abs(q[2] - true_rul) / true_rul, 0.0)),
                     "width90": _relative_width(q[0], q[4], true_rul),
                     "width50": _relative_width(q[1], q[3], true_rul),
                     "guard_widening": float(widening)})
    return rows


def summarise(results: list[dict]) -> dict:
    rows = [r for u in results for r in u["rows"]]
    pit = np.array([r["pit"] for r in rows])
    hist = np.histogram(pit, bins=10, range=(0.0, 1.0))[0] / pit.size

    def figures(sel: list[dict]) -> dict:
        rr = [r for u in sel for r in u["rows"]]
        cra = [float(np.mean([r["ra"] for r in u["rows"]])) for u in sel]
        # alpha-lambda: the prediction nearest lambda = 0.5 between 40 % of life and EOL
        al = [min(u["rows"], key=lambda r: abs(r["frac"] - 0.7)) for u in sel]
        # 90 % bootstrap intervals over units (each unit's 8 predictions are one cluster)
        in50 = [float(np.mean([r["in50"] for r in u["rows"]])) for u in sel]
        in90 = [float(np.mean([r["in90"] for r in u["rows"]])) for u in sel]
        idx = bootstrap_indices(len(sel))
        return {"units": len(sel), "predictions": len(rr),
                "coverage50": float(np.mean(in50)),
                "coverage50_interval": bootstrap_mean_interval(in50, indices=idx),
                "coverage90": float(np.mean(in90)),
                "coverage90_interval": bootstrap_mean_interval(in90, indices=idx),
                "cra": float(np.mean(cra)),
                "cra_interval": bootstrap_mean_interval(cra, indices=idx),
                "alpha_lambda_pass": float(np.mean([abs(1.0 - r["ra"]) <= 0.2 for r in al])),
                "median_width90_rel": float(np.median(
                    [r["width90"] if r["width90"] is not None else np.inf for r in rr])),
                "median_width50_rel": float(np.median(
                    [r["width50"] if r["width50"] is not None else np.inf for r in rr])),
                "mean_guard_widening": float(np.mean([r["guard_widening"] for r in rr])),
                "guard_widened_share": float(np.mean([r["guard_widening"] > 0 for r in rr]))}
    out = {"all": figures(results), "pit_histogram": hist.round(4).tolist()}
    out["by_family"] = {f: figures([u for u in results if u["family"] == f]) for f in FAMILIES}
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--units-per-family", type=int, default=20)
    ap.add_argument("--half", choices=("tuning", "held-out"), default="tuning")
    ap.add_argument("--out", type=Path, default=None)
    ap.add_argument("--progpy", action="store_true",
                    help="also score progpy's particle filter (linear fade) on the same units")
    ap.add_argument("--memory-spans", type=float, default=None,
                    help="override the engine's default (choosing it: tuning half only)")
    ap.add_argument("--rate-prior", choices=("log-uniform", "uniform"), default=None,
                    help="override the engine's prior over the affine and exponential rates")
    for name, kind in GUARD_OPTIONS.items():
        ap.add_argument(f"--{name.replace('_', '-')}", type=kind, default=None,
                        help=f"override LawAverageConfig.{name} (0 prefixes: no guard)")
    args = ap.parse_args(argv)
    global CONFIG
    overrides: dict = {}
    if args.memory_spans is not None:
        overrides["memory_spans"] = args.memory_spans
    if args.rate_prior is not None:
        overrides["rate_prior"] = args.rate_prior
    for name in GUARD_OPTIONS:
        if getattr(args, name) is not None:
            overrides[name] = getattr(args, name)
    if overrides:
        CONFIG = LawAverageConfig(**overrides)
    cfg = CONFIG or LawAverageConfig()
    parity = 0 if args.half == "tuning" else 1
    start = time.perf_counter()
    results, theirs = [], []
    for family in FAMILIES:
        for draw in range(parity, 2 * args.units_per_family, 2):
            unit = make_unit(family, draw)
            results.append({"family": family, "draw": draw,
                            "rows": score_unit(unit, ours_at(unit))})
            if args.progpy:
                theirs.append({"family": family, "draw": draw,
                               "rows": score_unit(unit, progpy_at(unit))})
    summary = {"half": args.half, "engine": "law averaging (server.phm.prognosis.forecast)",
               "guard": {name: getattr(cfg, name) for name in GUARD_OPTIONS},
               "seconds": round(time.perf_counter() - start, 1), **summarise(results)}
    if theirs:
        summary["progpy_linear_pf"] = summarise(theirs)
    out = args.out or ROOT / "docs" / "results" / f"rul_calibration_{args.half}.json"
    out.write_text(json.dumps(summary, indent=1) + "\n")
    print(json.dumps({k: summary[k] for k in ("all", "pit_histogram", "seconds")}, indent=1))
    if theirs:
        print("progpy", json.dumps(summary["progpy_linear_pf"]["all"]))
    for f, v in summary["by_family"].items():
        print(f"{f:15s} c50 {v['coverage50']:.2f} c90 {v['coverage90']:.2f} "
              f"CRA {v['cra']:.2f} al {v['alpha_lambda_pass']:.2f} "
              f"w50 {v['median_width50_rel']:.2f} w90 {v['median_width90_rel']:.2f} "
              f"guard {v['mean_guard_widening']:.3f} ({v['guard_widened_share']:.2f})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
