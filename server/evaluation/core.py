"""Evaluation of the whole PHM chain on a simulated campaign (paper sections 4.3 and 5).

Every pattern of the campaign is run flight by flight through
:func:`server.phm.chain.analyze_flight`
exactly as the service runs it: fresh :class:`~server.phm.chain.ActuatorHealth` for the three
actuators of the pattern's aircraft at the pattern start, state carried between flights, the
manifest's flight ``index`` passed as ``flight_index`` (fault-to-failure runs render only every
n-th flight; the particle filter propagates over the gaps). The labels of the campaign (mode,
onset, failure flight, true RUL) are read only to score the outcomes.

Scored here:

- false alarms on healthy cycles (healthy patterns and the pre-onset flights of fault patterns);
- detection rate and detection time per mode (% of life and flights after onset);
- confusion matrix of the classification of the faulty actuator at its first alarm and at the
  last flight of each faulty pattern (true mode vs argmax class probability), per-class rates;
- prognosis of the progressive modes: 10 prediction instants equally spaced from detection to
  end of life (``t_d + i (t_eol - t_d) / 10``, i = 0..9; the instant at end of life itself has
  no relative accuracy), each mapped to the rendered flight nearest to it (duplicates merged),
  the RUL median of the chain's distribution at that flight as point estimate; prognostic
  horizon with the +-20 % cone ("falls and remains") normalised over the simulated life
  (failure - onset); mean relative accuracy; alpha-lambda (alpha 0.2, lambda 0.5); CRA with
  weights growing toward end of life; convergence of the relative error on the normalised
  time axis.

Time unit: flights. No threshold is tuned here: the model comes trained from the design campaign.
"""

from __future__ import annotations

import math
import os
import zlib
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from contextlib import nullcontext
from pathlib import Path
from typing import Any

import numpy as np

from server.campaigns import load_campaign
from server.phm import metrics
from server.phm.chain import MeasurementHook, PhmModel, analyze_flight
from server.phm.dataset import Campaign, Pattern
from server.phm.prognosis.document import rul_point, rul_quantile
from server.vocabulary import PAPER_TABLE2, POSITIONS, PROGRESSIVE, alarming_positions

from .timing import ChainTimer, feature_timing

__all__ = [
    "ALPHA",
    "LAMBDA",
    "N_PREDICTIONS",
    "PAPER_TABLE2",
    "expected_units",
    "pattern_seed",
    "run_pattern",
    "prediction_instants",
    "select_prediction_flights",
    "pattern_prognosis",
    "summarise_prognosis",
    "summarise_detection",
    "confusion",
    "evaluate_patterns",
    "evaluate_campaign",
]

ALPHA = 0.2
LAMBDA = 0.5
N_PREDICTIONS = 10
#: point estimate scored by the metrics: "median" or "mode" (the most probable RUL, the
#: paper's)
POINT_ESTIMATE = "median"
_POINT_ESTIMATES = ("median", "mode")
UNDETECTED = "undetected"

Progress = Callable[[int, int], None]


def expected_units(mode: str, position: str | None) -> set[str]:
    """Actuators expected to alarm for a fault (both winglet actuators for rod-end wear)."""
    return alarming_positions(mode, position)


def pattern_seed(pattern_id: str) -> int:
    """Filter seed of a pattern: a stable hash of its id (independent of worker count)."""
    return zlib.crc32(pattern_id.encode()) & 0x7FFFFFFF


def _noise_free_hook(model: PhmModel, pattern: Pattern, severity_norm: float
                     ) -> MeasurementHook:
    """The faulty actuator's own feature (the pattern's mode's) replaced by its noise-free
    value h(true severity) of the trained measurement model; a flight without a value stays
    without, the other actuators and features are untouched."""
    spec = model.measurement[pattern.mode]
    position = str(pattern.position)
    value = float(spec.model_for(position).predict(np.array([severity_norm]))[0])

    def hook(pos: str, values: dict[str, float]) -> dict[str, float]:
        if pos != position or values.get(spec.feature) is None:
            return values
        return {**values, spec.feature: value}

    return hook


def run_pattern(model: PhmModel, pattern: Pattern, *, timer: ChainTimer | None = None,
                noise_free: bool = False) -> dict[str, Any]:
    """Run the chain over one pattern; return its per-flight trace (JSON-safe).

    Per flight: the faulty actuator's alarm, class probabilities, mode in use and RUL quantiles,
    plus the positions alarmed and newly alarmed (all three actuators are monitored).
    ``noise_free``: from the fault's onset, the prognosis of the faulty actuator sees its
    mode's own feature without noise, h(true severity) (an error budget: what is left is the
    degradation law's extrapolation; detection and classification see the real features).
    """
    health = {pos: model.new_health(pos) for pos in POSITIONS}
    seed = pattern_seed(pattern.id)
    faulty = pattern.position if pattern.mode != "healthy" else None
    budget = noise_free and faulty is not None and pattern.mode in model.measurement
    onset = int(pattern.onset_flight or 0)
    flights: list[dict[str, Any]] = []
    for rec in pattern.flights:
        hook = (_noise_free_hook(model, pattern, rec.severity_norm)
                if budget and rec.index >= onset else None)
        with timer.span("chain") if timer is not None else nullcontext():
            out = analyze_flight(model, rec.features, health, seed=seed, flight_index=rec.index,
                                 started_at=rec.started_at, base=pattern.base,
                                 measurement_hook=hook)
        o = out.get(faulty) if faulty else None
        flights.append({
            "index": rec.index,
            "severity_norm": rec.severity_norm,
            "true_rul": rec.true_rul_flights,
            "alarms": sorted(p for p, v in out.items() if v.alarm),
            "new_alarms": sorted(p for p, v in out.items() if v.new_alarm),
            "alarm": bool(o.alarm) if o is not None else None,
            "probs": dict(o.class_probabilities) if o is not None and o.class_probabilities
            else None,
            "fault_mode": o.fault_mode if o is not None else None,
            "rul": o.rul.to_dict() if o is not None and o.rul is not None else None,
        })
    return {"id": pattern.id, "aircraft": pattern.aircraft, "mode": pattern.mode,
            "position": pattern.position, "onset": pattern.onset_flight,
            "failure": pattern.failure_flight, "seed": seed,
            "horizon": float(model.prognoser.max_horizon_flights), "flights": flights}


# ----------------------------------------------------------------------------------------------
# detection and classification


def _onset(trace: Mapping[str, Any]) -> int:
    return int(trace["onset"]) if trace["onset"] is not None else 0


def detection_of(trace: Mapping[str, Any]) -> dict[str, Any]:
    """Detection facts of one pattern: first alarm of the faulty actuator, false alarms."""
    healthy = trace["mode"] == "healthy"
    onset = _onset(trace)
    expected = expected_units(trace["mode"], trace["position"])
    detected: int | None = None
    first_probs = None
    false_alarms = 0  # new alarms on healthy flights (any actuator)
    other = 0  # new alarms after onset on actuators not expected to alarm
    healthy_flights = 0
    for f in trace["flights"]:
        pre = healthy or f["index"] < onset
        if pre:
            healthy_flights += 1
            false_alarms += len(f["new_alarms"])
            continue
        other += sum(1 for p in f["new_alarms"] if p not in expected)
        if detected is None and f["alarm"]:
            detected = int(f["index"])
            first_probs = f["probs"]
    last = trace["flights"][-1] if trace["flights"] else None
    last_probs = last["probs"] if last is not None and last["alarm"] else None
    failure = trace["failure"]
    pct = None
    if detected is not None and failure is not None and failure > onset:
        pct = 100.0 * (detected - onset) / (failure - onset)
    return {"detected_index": detected,
            "flights_after_onset": None if detected is None else detected - onset,
            "pct_life": pct, "false_alarms": false_alarms, "healthy_flights": healthy_flights,
            "other_unit_alarms": other, "first_probs": first_probs, "last_probs": last_probs}


def _argmax(probs: Mapping[str, float] | None) -> str:
    if not probs:
        return UNDETECTED
    return max(sorted(probs), key=lambda c: probs[c])


def summarise_detection(traces: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """False alarms on healthy cycles, detection rate and time per mode."""
    dets = [(t, detection_of(t)) for t in traces]
    healthy = [(t, d) for t, d in dets if t["mode"] == "healthy"]
    fa_events = sum(d["false_alarms"] for _, d in dets)
    h_flights = sum(d["healthy_flights"] for _, d in dets)
    fa = {"healthy_patterns": len(healthy),
          "healthy_patterns_with_alarm": sum(1 for _, d in healthy if d["false_alarms"] > 0),
          "healthy_flights": h_flights, "false_alarm_events": fa_events,
          "rate_per_flight": fa_events / h_flights if h_flights else None,
          "pre_onset_alarms_in_fault_patterns": sum(d["false_alarms"] for t, d in dets
                                                   if t["mode"] != "healthy")}
    per_mode: dict[str, Any] = {}
    for mode in sorted({t["mode"] for t, _ in dets if t["mode"] != "healthy"}):
        rows = [(t, d) for t, d in dets if t["mode"] == mode]
        found = [d for _, d in rows if d["detected_index"] is not None]
        pct = np.array([d["pct_life"] for d in found if d["pct_life"] is not None])
        aft = np.array([d["flights_after_onset"] for d in found], dtype=float)
        per_mode[mode] = {
            "patterns": len(rows), "detected": len(found),
            "rate": len(found) / len(rows) if rows else None,
            "pct_life_mean": float(pct.mean()) if pct.size else None,
            "pct_life_max": float(pct.max()) if pct.size else None,
            "flights_after_onset_mean": float(aft.mean()) if aft.size else None,
            "flights_after_onset_max": float(aft.max()) if aft.size else None,
            "other_unit_alarms": sum(d["other_unit_alarms"] for _, d in rows),
            "missed": [t["id"] for t, d in rows if d["detected_index"] is None],
        }
    return {"false_alarms": fa, "per_mode": per_mode}


def confusion(true: Sequence[str], predicted: Sequence[str], classes: Sequence[str]
              ) -> dict[str, Any]:
    """Confusion matrix (rows true, columns predicted + ``undetected``) and per-class rates."""
    cols = [*classes, UNDETECTED]
    rows = [c for c in classes if c in set(true)] + sorted(set(true) - set(classes))
    m = np.zeros((len(rows), len(cols)), dtype=int)
    for t, p in zip(true, predicted, strict=True):
        m[rows.index(t), cols.index(p if p in cols else UNDETECTED)] += 1
    per_class = {}
    for i, c in enumerate(rows):
        n = int(m[i].sum())
        j = cols.index(c) if c in cols else None
        tp = int(m[i, j]) if j is not None else 0
        col_total = int(m[:, j].sum()) if j is not None else 0
        per_class[c] = {"n": n, "recall": tp / n if n else None,
                        "precision": tp / col_total if col_total else None}
    total = int(m.sum())
    correct = sum(int(m[i, cols.index(c)]) for i, c in enumerate(rows) if c in cols)
    return {"rows": rows, "columns": cols, "matrix": m.tolist(),
            "accuracy": correct / total if total else None, "per_class": per_class}


def classification_summary(traces: Sequence[Mapping[str, Any]], classes: Sequence[str]
                           ) -> dict[str, Any]:
    faulty = [t for t in traces if t["mode"] != "healthy"]
    dets = [detection_of(t) for t in faulty]
    true = [t["mode"] for t in faulty]
    return {"classes": list(classes),
            "at_first_alarm": confusion(true, [_argmax(d["first_probs"]) for d in dets],
                                        classes),
            "at_last_flight": confusion(true, [_argmax(d["last_probs"]) for d in dets], classes)}


# ----------------------------------------------------------------------------------------------
# prognosis


def prediction_instants(t_detect: float, t_eol: float, n: int = N_PREDICTIONS) -> np.ndarray:
    """``n`` instants equally spaced from detection (included) toward end of life (excluded)."""
    if t_eol <= t_detect:
        return np.empty(0)
    return t_detect + (t_eol - t_detect) * np.arange(n) / n


def select_prediction_flights(candidates: Sequence[int], instants: np.ndarray) -> np.ndarray:
    """The candidate flight nearest each instant (earlier one on ties), duplicates merged."""
    c = np.asarray(sorted(candidates), dtype=float)
    if c.size == 0 or instants.size == 0:
        return np.empty(0, dtype=int)
    idx = np.abs(c[np.newaxis, :] - instants[:, np.newaxis]).argmin(axis=1)
    return np.unique(c[idx]).astype(int)


def pattern_prognosis(trace: Mapping[str, Any], *, alpha: float = ALPHA, lam: float = LAMBDA,
                      n: int = N_PREDICTIONS, point_estimate: str = POINT_ESTIMATE
                      ) -> dict[str, Any]:
    """Prognostic metrics of one progressive pattern from its trace.

    A selected flight without a RUL distribution (the actuator classified as a mode without
    prognosis) counts as a prediction outside the cone and has no relative accuracy. A point
    estimate beyond the prediction horizon counts as the horizon (``max_horizon_flights``).
    ``point_estimate`` is the RUL scored: "median" or "mode" (the most probable RUL).
    """
    if point_estimate not in _POINT_ESTIMATES:
        raise ValueError(f"point_estimate must be one of {sorted(_POINT_ESTIMATES)}, "
                         f"got {point_estimate!r}")
    onset = _onset(trace)
    t_eol = float(trace["failure"])
    life = t_eol - onset
    det = detection_of(trace)["detected_index"]
    out: dict[str, Any] = {"id": trace["id"], "aircraft": trace["aircraft"],
                           "position": trace["position"], "t_eol": t_eol, "life": life,
                           "detected_index": det, "predictions": [], "ph": 0.0,
                           "ph_flights": 0.0, "ph_from_detection": 0.0, "ph_band": 0.0,
                           "ra": None,
                           "alpha_lambda": False, "cra": None, "convergence": None,
                           "point_estimate": point_estimate}
    if det is None:
        return out
    by_index = {int(f["index"]): f for f in trace["flights"]}
    cands = [i for i in by_index if det <= i < t_eol]
    inst = prediction_instants(float(det), t_eol, n)
    chosen = select_prediction_flights(cands, inst)
    if chosen.size == 0:
        return out
    horizon = float(trace.get("horizon", math.inf))

    def point(i: int) -> float:
        rul = by_index[i]["rul"]
        if not rul:
            return math.nan
        value = rul_point(rul, point_estimate)
        return horizon if value is None else value

    est = np.array([point(int(i)) for i in chosen], dtype=float)
    times = chosen.astype(float)
    true = t_eol - times
    ph = metrics.prognostic_horizon(times, est, t_eol, alpha=alpha, bounds="relative", stay=True)
    out["ph_flights"] = ph
    out["ph"] = ph / life
    # Saxena's constant-width bounds, +-alpha x life around the true RUL (time from onset)
    out["ph_band"] = metrics.prognostic_horizon(times - onset, est, life, alpha=alpha,
                                                bounds="eol", stay=True) / life
    out["ph_from_detection"] = ph / (t_eol - det)
    out["alpha_lambda"] = metrics.alpha_lambda(times, est, t_eol, alpha=alpha, lam=lam,
                                               t_p=float(det))
    ok = np.isfinite(est)
    if ok.any():
        out["ra"] = metrics.mean_relative_accuracy(est[ok], true[ok])
        out["cra"] = metrics.cumulative_relative_accuracy(
            est[ok], true[ok], weights=np.arange(1, int(ok.sum()) + 1, dtype=float))
    if ok.sum() >= 2:
        err = np.abs(est[ok] - true[ok]) / true[ok]
        out["convergence"] = metrics.convergence((times[ok] - onset) / life, err,
                                                 t_p=(det - onset) / life)
    out["predictions"] = [
        {"flight": int(i), "true_rul": float(t), "point": None if not math.isfinite(m) else m,
         "q05": rul_quantile(by_index[int(i)]["rul"], 0.05),
         "q95": rul_quantile(by_index[int(i)]["rul"], 0.95),
         "mode_used": by_index[int(i)]["fault_mode"],
         "in_cone": bool(metrics.alpha_bounds_hit(m, t, alpha=alpha)) if math.isfinite(m)
         else False}
        for i, t, m in zip(chosen, true, est, strict=True)]
    out["instants"] = inst.tolist()
    return out


def _mean(values: Sequence[float | None]) -> float | None:
    v = [x for x in values if x is not None and math.isfinite(x)]
    return float(np.mean(v)) if v else None


def summarise_prognosis(traces: Sequence[Mapping[str, Any]], *, alpha: float = ALPHA,
                        lam: float = LAMBDA, point_estimate: str = POINT_ESTIMATE
                        ) -> dict[str, Any]:
    """Per progressive mode: per-pattern metrics and their averages (PH of an undetected
    pattern counts as 0; RA is averaged over the patterns that have predictions)."""
    out: dict[str, Any] = {}
    for mode in PROGRESSIVE:
        pats = [pattern_prognosis(t, alpha=alpha, lam=lam, point_estimate=point_estimate)
                for t in traces
                if t["mode"] == mode and t["failure"] is not None]
        if not pats:
            continue
        ra = _mean([p["ra"] for p in pats])
        out[mode] = {
            "ph": _mean([p["ph"] for p in pats]),
            "ra": None if ra is None else 100.0 * ra,
            "ra_fraction": ra,
            "ra_median_pattern": None if not [p for p in pats if p["ra"] is not None] else
            100.0 * float(np.median([p["ra"] for p in pats if p["ra"] is not None])),
            "ph_from_detection": _mean([p["ph_from_detection"] for p in pats]),
            "ph_band": _mean([p["ph_band"] for p in pats]),
            "alpha_lambda": _mean([float(p["alpha_lambda"]) for p in pats]),
            "cra": _mean([p["cra"] for p in pats]),
            "convergence": _mean([p["convergence"] for p in pats]),
            "n_patterns": len(pats),
            "n_with_predictions": sum(1 for p in pats if p["predictions"]),
            "paper": {"ph": PAPER_TABLE2[mode][0], "ra": PAPER_TABLE2[mode][1]},
            "patterns": pats,
        }
    return out


# ----------------------------------------------------------------------------------------------
# running


_WORKER_MODEL: PhmModel | None = None
_WORKER_NOISE_FREE = False


def _init_worker(model_doc: dict[str, Any], noise_free: bool = False) -> None:
    global _WORKER_MODEL, _WORKER_NOISE_FREE
    _WORKER_MODEL = PhmModel.from_dict(model_doc)
    _WORKER_NOISE_FREE = noise_free


def _work(pattern: Pattern) -> tuple[dict[str, Any], dict[str, Any]]:
    assert _WORKER_MODEL is not None
    timer = ChainTimer()
    with timer.instrument():
        trace = run_pattern(_WORKER_MODEL, pattern, timer=timer, noise_free=_WORKER_NOISE_FREE)
    return trace, timer.to_dict()


def evaluate_patterns(model: PhmModel, patterns: Sequence[Pattern], *, jobs: int = 1,
                      progress: Progress | None = None, noise_free: bool = False
                      ) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """Traces of all patterns (in the given order) and the merged chain timings.

    The model goes to the workers as its JSON document (and is rebuilt from it in the serial
    case too), so the results do not depend on ``jobs``. ``noise_free``: see
    :func:`run_pattern`.
    """
    doc = model.to_dict()
    order = sorted(range(len(patterns)), key=lambda i: -len(patterns[i].flights))
    results: dict[int, tuple[dict[str, Any], dict[str, Any]]] = {}
    if jobs <= 1:
        _init_worker(doc, noise_free)
        for k, i in enumerate(order):
            results[i] = _work(patterns[i])
            if progress is not None:
                progress(k + 1, len(patterns))
    else:
        with ProcessPoolExecutor(max_workers=jobs, initializer=_init_worker,
                                 initargs=(doc, noise_free)) as ex:
            futs = {ex.submit(_work, patterns[i]): i for i in order}
            for k, fut in enumerate(as_completed(futs)):
                results[futs[fut]] = fut.result()
                if progress is not None:
                    progress(k + 1, len(patterns))
    traces = [results[i][0] for i in range(len(patterns))]
    timing = ChainTimer.merge([results[i][1] for i in range(len(patterns))])
    return traces, timing


def evaluate_campaign(model: PhmModel, campaign_dir: str | os.PathLike[str], *, jobs: int = 1,
                      progress: Progress | None = None, timing_flights: int = 6,
                      campaign: Campaign | None = None,
                      point_estimate: str = POINT_ESTIMATE,
                      noise_free: bool = False) -> dict[str, Any]:
    """Run the chain over every pattern of a campaign and score it (JSON-safe dict).

    ``timing_flights`` flights are re-read and their features recomputed (serially) to time
    feature extraction; 0 skips that measurement. ``point_estimate``: the RUL the prognostic
    metrics score, "median" or "mode". ``noise_free``: the prognosis sees noise-free own
    features (an error budget, :func:`run_pattern`).
    """
    root = Path(campaign_dir)
    camp = campaign or load_campaign(root, jobs=max(jobs, 1))
    traces, chain_timing = evaluate_patterns(model, camp.patterns, jobs=jobs, progress=progress,
                                             noise_free=noise_free)
    classes = ([str(c) for c in model.classifier.classes_.tolist()]
               if model.classifier is not None else [])
    feat = feature_timing(root, n_flights=timing_flights) if timing_flights > 0 else None
    import json

    manifest = json.loads((root / "manifest.json").read_text())
    return {
        "format": "ema-evaluation/1",
        "campaign": {"dir": str(root.resolve()), "kind": camp.kind, "seed": camp.seed,
                     "scale": manifest.get("scale"), "render_every": manifest.get("render_every"),
                     "duration_s": manifest.get("duration_s"),
                     "patterns": len(camp.patterns),
                     "flights": sum(len(p.flights) for p in camp.patterns),
                     "aircraft": [{"tail": a.get("tail"), "base": a.get("base"),
                                   "climate": a.get("climate")} for a in camp.aircraft]},
        "settings": {"alpha": ALPHA, "lambda": LAMBDA, "n_predictions": N_PREDICTIONS,
                     "point_estimate": point_estimate, "ph_normalisation": "failure - onset",
                     "prognosis_features": "noise-free h(true severity)" if noise_free
                     else "measured",
                     "cra_weights": "1..n (growing toward end of life)",
                     "convergence_axis": "(t - onset) / life", "jobs": jobs},
        "detection": summarise_detection(traces),
        "classification": classification_summary(traces, classes),
        "prognosis": summarise_prognosis(traces, point_estimate=point_estimate),
        "timing": _timing_summary(chain_timing, feat, model),
        "patterns": traces,
    }


def _timing_summary(chain: Mapping[str, Any], feat: Mapping[str, Any] | None,
                    model: PhmModel) -> dict[str, Any]:
    def mean_ms(key: str) -> float | None:
        c = chain.get(key)
        return 1e3 * c["total_s"] / c["calls"] if c and c["calls"] else None

    out: dict[str, Any] = {
        "calls": {k: v["calls"] for k, v in chain.items()},
        "chain_per_flight_ms": mean_ms("chain"),
        "zscores_per_flight_ms": mean_ms("zscores"),
        "detector_update_ms": mean_ms("detector"),
        "classifier_ms": mean_ms("classifier"),
        "pf_update_ms": mean_ms("pf_update"),
        "rls_ms": mean_ms("rls"),
        "pf_predict_ms": mean_ms("pf_predict"),
        "n_particles": model.prognoser.n_particles,
    }
    upd, rls, pred = out["pf_update_ms"], out["rls_ms"], out["pf_predict_ms"]
    if upd and pred and rls is not None:
        out["pf_cycle_ms"] = upd + pred
        out["rls_share_pct"] = 100.0 * rls / (upd + pred)
        out["rls_share_of_update_pct"] = 100.0 * rls / upd
    det_flight = None
    if out["zscores_per_flight_ms"] is not None and out["detector_update_ms"] is not None:
        per_flight_units = chain["detector"]["calls"] / max(chain["zscores"]["calls"], 1)
        det_flight = out["zscores_per_flight_ms"] + out["detector_update_ms"] * per_flight_units
        out["detection_per_flight_ms"] = det_flight
    if feat is not None:
        out["features"] = dict(feat)
        steps = feat.get("steps_80hz_mean")
        if steps:
            out["features_per_step_ms"] = feat["features_per_flight_ms"] / steps
            out["read_per_step_ms"] = feat["read_per_flight_ms"] / steps
            if det_flight is not None:
                out["detection_per_step_ms"] = det_flight / steps
                out["features_detection_per_step_ms"] = (
                    feat["features_per_flight_ms"] + det_flight) / steps
    out["paper"] = {"features_detection_per_step_ms": 11.3, "pf_cycle_ms": 7.4,
                    "rls_share_pct": 2.25}
    return out
