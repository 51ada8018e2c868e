"""Scoring the traces of a campaign's patterns: detection, classification, prognosis.

Scored here:

- false alarms on healthy cycles (healthy patterns and the pre-onset flights of fault patterns);
- detection rate and detection time per mode (% of life and flights after onset);
- confusion matrix of the classification of the faulty actuator at its first alarm and at the
  last flight of each faulty pattern (true mode vs argmax class probability), per-class rates;
- prognosis of the progressive modes: 10 prediction instants equally spaced from detection to
  end of life (``t_d + i (t_eol - t_d) / 10``, i = 0..9; the instant at end of life itself has
  no relative accuracy), each mapped to the rendered flight nearest to it (duplicates merged),
  the RUL median of the chain's distribution at that flight as point estimate (the most
  probable RUL reported beside it); prognostic horizon ``ph`` after Saxena ("falls and
  remains" within true RUL +- alpha x life) and ``ph_cone`` with the +-20 % relative cone,
  both normalised over the simulated life (failure - onset); mean relative accuracy;
  alpha-lambda (alpha 0.2, lambda 0.5); CRA with weights growing toward end of life;
  convergence of the relative error on the normalised time axis; calibration of the RUL
  distribution (share of the predictions whose central 50 % and 90 % intervals hold the
  true RUL).

Every mean comes with a 90 % percentile bootstrap interval over patterns (``<key>_ci``:
[lo, hi]; 2000 resamples of the mode's patterns with replacement, seed 0; [x, x] with one
pattern, None with none). The false-alarm rate per healthy flight is resampled over the
patterns with healthy flights, each pattern's flights one cluster.

Time unit: flights. No threshold is tuned here: the model comes trained from the design campaign.

A mean without any value (e.g. RA of a mode none of whose patterns was detected) is None, and
so is its interval. Per-class recall is the accuracy on that true mode.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import asdict
from typing import Any

import numpy as np

from server.phm import metrics
from server.phm.classification import confusion as count_confusion
from server.phm.classification.confirmation import (
    CONFIRMATION,
    ConfirmationRule,
    first_confirmation,
)
from server.phm.prognosis.document import rul_point, rul_quantile
from server.vocabulary import PAPER_TABLE2, PROGRESSIVE, alarming_positions

from .bootstrap import finite_max, interval, mean_ci, nan_if_none, resamples
from .false_alarms import summarise_false_alarms
from .isolation import summarise_isolation

ALPHA = 0.2
LAMBDA = 0.5
N_PREDICTIONS = 10
#: point estimate scored by the metrics: "median" or "mode" (the most probable RUL, the
#: paper's)
POINT_ESTIMATE = "median"
_POINT_ESTIMATES = ("median", "mode")
UNDETECTED = "undetected"
#: a detected fault whose class the rule never confirmed (a column of its own)
UNCONFIRMED = "unconfirmed"


def expected_units(mode: str, position: str | None, pair_rod_ends: bool = False) -> set[str]:
    """Actuators expected to alarm for a fault (both winglet actuators for rod-end wear on an
    active-active tab)."""
    return alarming_positions(mode, position, pair_rod_ends=pair_rod_ends)


def _onset(trace: Mapping[str, Any]) -> int:
    return int(trace["onset"]) if trace["onset"] is not None else 0


def detection_of(trace: Mapping[str, Any]) -> dict[str, Any]:
    """Detection facts of one pattern: first alarm of the faulty actuator, false alarms."""
    healthy = trace["mode"] == "healthy"
    onset = _onset(trace)
    expected = expected_units(trace["mode"], trace["position"],
                              bool(trace.get("pair_rod_ends", False)))
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


def summarise_sensors(traces: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """Sensor findings over the campaign: per ``"<channel> <metric>"`` the flights with it,
    and how many flights of healthy cycles and of fault patterns had any."""
    per: dict[str, int] = {}
    flights = healthy = with_any = healthy_with_any = 0
    for t in traces:
        is_healthy = t["mode"] == "healthy"
        for f in t["flights"]:
            found = f.get("sensor") or []
            flights += 1
            healthy += is_healthy
            with_any += bool(found)
            healthy_with_any += bool(found) and is_healthy
            for key in found:
                per[key] = per.get(key, 0) + 1
    return {"flights": flights, "flights_with_finding": with_any,
            "healthy_cycle_flights": healthy,
            "healthy_cycle_flights_with_finding": healthy_with_any,
            "by_channel": dict(sorted(per.items()))}


def summarise_detection(traces: Sequence[Mapping[str, Any]],
                        design_rate: float | None = None) -> dict[str, Any]:
    """False alarms on healthy cycles, detection rate and time per mode, with bootstrap
    intervals: the false-alarm rate per healthy flight resampled over the patterns that have
    healthy flights (each pattern's flights a cluster), the per-mode figures over the mode's
    patterns; and the false alarms per unit-flight of every unit without a fault, beside the
    detector's ``design_rate`` (:mod:`server.evaluation.false_alarms`)."""
    dets = [(t, detection_of(t)) for t in traces]
    healthy = [(t, d) for t, d in dets if t["mode"] == "healthy"]
    fa_events = sum(d["false_alarms"] for _, d in dets)
    h_flights = sum(d["healthy_flights"] for _, d in dets)
    clusters = [d for _, d in dets if d["healthy_flights"] > 0]
    rate_ci = interval([d["false_alarms"] / d["healthy_flights"] for d in clusters],
                       resamples(len(clusters)),
                       weights=[d["healthy_flights"] for d in clusters])
    fa = {"healthy_patterns": len(healthy),
          "healthy_patterns_with_alarm": sum(1 for _, d in healthy if d["false_alarms"] > 0),
          "healthy_flights": h_flights, "false_alarm_events": fa_events,
          "rate_per_flight": fa_events / h_flights if h_flights else None,
          "rate_per_flight_ci": rate_ci, "clusters": len(clusters),
          "pre_onset_alarms_in_fault_patterns": sum(d["false_alarms"] for t, d in dets
                                                   if t["mode"] != "healthy")}
    per_mode: dict[str, Any] = {}
    for mode in sorted({t["mode"] for t, _ in dets if t["mode"] != "healthy"}):
        rows = [(t, d) for t, d in dets if t["mode"] == mode]
        per_mode[mode] = _mode_detection(rows)
    return {"false_alarms": fa,
            "per_unit_flight": summarise_false_alarms(traces, design_rate),
            "isolation": summarise_isolation(traces),
            "per_mode": per_mode}


def _mode_detection(rows: Sequence[tuple[Mapping[str, Any], Mapping[str, Any]]]
                    ) -> dict[str, Any]:
    """Detection figures of one mode's patterns (undetected ones have no time)."""
    idx = resamples(len(rows))
    found = [d for _, d in rows if d["detected_index"] is not None]
    hit = [float(d["detected_index"] is not None) for _, d in rows]
    pct = [nan_if_none(d["pct_life"]) for _, d in rows]
    aft = [nan_if_none(d["flights_after_onset"]) for _, d in rows]
    out: dict[str, Any] = {"patterns": len(rows), "detected": len(found)}
    out.update(mean_ci("rate", hit, idx))
    out.update(mean_ci("pct_life_mean", pct, idx))
    out["pct_life_max"] = finite_max(pct)
    out.update(mean_ci("flights_after_onset_mean", aft, idx))
    out["flights_after_onset_max"] = finite_max(aft)
    out["other_unit_alarms"] = sum(d["other_unit_alarms"] for _, d in rows)
    out["missed"] = [t["id"] for t, d in rows if d["detected_index"] is None]
    return out


def confusion(true: Sequence[str], predicted: Sequence[str], classes: Sequence[str],
              extra: Sequence[str] = ()) -> dict[str, Any]:
    """Confusion matrix (rows true, columns predicted + ``extra`` + ``undetected``) and
    per-class rates; ``extra``: other outcomes with a column of their own (``unconfirmed``).

    ``accuracy_ci`` and each class's ``recall_ci`` (the accuracy on that true mode) are
    bootstrap intervals over the rows (patterns); precision has none.
    """
    cols = [*classes, *extra, UNDETECTED]
    rows = [c for c in classes if c in set(true)] + sorted(set(true) - set(classes))
    # counted by the classifier's report (the one owner of the matrix) over every label of
    # either axis; this view keeps the true modes seen as rows and the undetected column
    axes = cols + [r for r in rows if r not in cols]
    counts = np.asarray(count_confusion(
        list(true), [p if p in cols else UNDETECTED for p in predicted], axes)["counts"])
    m = counts[np.ix_([axes.index(r) for r in rows], [axes.index(c) for c in cols])]
    correct = np.array([float(t in cols and p == t) for t, p in zip(true, predicted,
                                                                     strict=True)])
    labels = np.array(list(true), dtype=object)
    per_class = {}
    for i, c in enumerate(rows):
        n = int(m[i].sum())
        j = cols.index(c) if c in cols else None
        tp = int(m[i, j]) if j is not None else 0
        col_total = int(m[:, j].sum()) if j is not None else 0
        mine = correct[labels == c]
        per_class[c] = {"n": n, "recall": tp / n if n else None,
                        "recall_ci": interval(mine, resamples(mine.size)),
                        "precision": tp / col_total if col_total else None}
    total = int(m.sum())
    return {"rows": rows, "columns": cols, "matrix": m.tolist(),
            "accuracy": float(correct.sum()) / total if total else None,
            "accuracy_ci": interval(correct, resamples(correct.size)),
            "per_class": per_class}


def confirmation_of(trace: Mapping[str, Any], detected: int | None,
                    rule: ConfirmationRule = CONFIRMATION) -> tuple[str, int | None]:
    """The faulty unit's class at confirmation and the flights from its first alarm to it
    (:mod:`server.phm.classification.confirmation` on the probabilities the trace kept)."""
    if detected is None:
        return UNDETECTED, None
    flights = [f for f in trace["flights"] if int(f["index"]) >= detected]
    found = first_confirmation(rule, [f["probs"] for f in flights])
    if found is None:
        return UNCONFIRMED, None
    i, mode = found
    return mode, int(flights[i]["index"]) - detected


def _flights_from(trace: Mapping[str, Any], index: int | None) -> int:
    return 0 if index is None else sum(int(f["index"]) >= index for f in trace["flights"])


def confirmation_delays(delays: Sequence[int | None]) -> dict[str, Any]:
    """Flights from the first alarm to confirmation: mean, 90th percentile, how many."""
    d = np.array([x for x in delays if x is not None], dtype=float)
    return {"confirmed": int(d.size), "unconfirmed": sum(x is None for x in delays),
            "mean": float(d.mean()) if d.size else None,
            "p90": float(np.percentile(d, 90)) if d.size else None,
            "max": float(d.max()) if d.size else None}


def classification_summary(traces: Sequence[Mapping[str, Any]], classes: Sequence[str]
                           ) -> dict[str, Any]:
    faulty = [t for t in traces if t["mode"] != "healthy"]
    dets = [detection_of(t) for t in faulty]
    true = [t["mode"] for t in faulty]
    confirmed = [confirmation_of(t, d["detected_index"]) for t, d in zip(faulty, dets,
                                                                          strict=True)]
    detected = [c for c in confirmed if c[0] != UNDETECTED]
    return {"classes": list(classes),
            "at_first_alarm": confusion(true, [_argmax(d["first_probs"]) for d in dets],
                                        classes),
            "at_confirmation": confusion(true, [m for m, _ in confirmed], classes,
                                         extra=(UNCONFIRMED,)),
            "confirmation_rule": asdict(CONFIRMATION),
            "flights_to_confirmation": {
                **confirmation_delays([k for _, k in detected]),
                # of the unconfirmed: the pattern ended before the rule could hold
                "ended_before_due": sum(
                    c[0] == UNCONFIRMED and _flights_from(t, d["detected_index"])
                    < CONFIRMATION.flights for t, d, c in zip(faulty, dets, confirmed,
                                                              strict=True))},
            "at_last_flight": confusion(true, [_argmax(d["last_probs"]) for d in dets], classes),
            "probability_calibration": {
                "at_first_alarm": probability_calibration(
                    true, [d["first_probs"] for d in dets]),
                "at_last_flight": probability_calibration(
                    true, [d["last_probs"] for d in dets])}}


def probability_calibration(true: Sequence[str], probs: Sequence[Mapping[str, float] | None]
                            ) -> dict[str, Any]:
    """How far the shown class probabilities can be taken at their word: the mean probability
    of the leading class against the share of leading classes that are right, the mean
    log-loss of the true class, and how many leading probabilities read 99 % or more."""
    rows = [(t, p) for t, p in zip(true, probs, strict=True) if p]
    if not rows:
        return {"n": 0, "mean_confidence": None, "accuracy": None, "log_loss": None,
                "at_least_99pct": 0}
    top = np.array([max(p.values()) for _, p in rows])
    right = np.array([_argmax(p) == t for t, p in rows], dtype=float)
    truth = np.array([p.get(t, 0.0) for t, p in rows])
    return {"n": len(rows), "mean_confidence": float(top.mean()),
            "accuracy": float(right.mean()),
            "log_loss": float(-np.mean(np.log(np.clip(truth, 1e-12, None)))),
            "at_least_99pct": int(np.sum(top >= 0.99))}


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
    prognosis) counts as a prediction outside the bounds, has no relative accuracy and misses
    both calibration intervals. A point estimate beyond the prediction horizon counts as the
    horizon (``max_horizon_flights``). ``point_estimate`` is the RUL scored: "median" or "mode"
    (the most probable RUL). ``ph`` is Saxena's horizon (every later estimate within true RUL
    +- alpha x life), ``ph_cone`` the +-alpha relative cone's; both normalised over the life.
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
                           "detected_index": det, "predictions": [],
                           **_horizons(np.empty(0), np.empty(0), onset, t_eol, det, alpha),
                           "ra": None, "alpha_lambda": False, "cra": None, "convergence": None,
                           "calibration": _no_calibration(),
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
    docs = [by_index[int(i)]["rul"] for i in chosen]
    out.update(_horizons(times, est, onset, t_eol, det, alpha))
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
    in50, in90 = _central_hits(docs, true, 0.25), _central_hits(docs, true, 0.05)
    out["calibration"] = {"n": int(true.size), "in_50": int(in50.sum()),
                          "in_90": int(in90.sum()),
                          **_widths(docs, 0.25, "50"), **_widths(docs, 0.05, "90")}
    out["predictions"] = [
        {"flight": int(i), "true_rul": float(t), "point": None if not math.isfinite(m) else m,
         "q05": rul_quantile(doc, 0.05), "q25": rul_quantile(doc, 0.25),
         "q75": rul_quantile(doc, 0.75), "q95": rul_quantile(doc, 0.95),
         "mode_used": by_index[int(i)]["fault_mode"],
         "hypothesis": ((doc or {}).get("hypothesis") or {}).get("name"),
         "in_cone": bool(metrics.alpha_bounds_hit(m, t, alpha=alpha)) if math.isfinite(m)
         else False, "in_50": bool(h50), "in_90": bool(h90)}
        for i, t, m, doc, h50, h90 in zip(chosen, true, est, docs, in50, in90, strict=True)]
    out["instants"] = inst.tolist()
    return out


def _horizons(times: np.ndarray, est: np.ndarray, onset: int, t_eol: float, det: int | None,
              alpha: float) -> dict[str, float]:
    """Saxena's horizon (``ph``: constant bounds +- alpha x life around the true RUL, on the
    time axis from onset) and the relative cone's (``ph_cone``: +- alpha x true RUL), both
    "falls and remains": in flights, over the life (failure - onset), over detection to
    failure. No prediction: all 0."""
    life = t_eol - onset
    if times.size == 0 or det is None:
        band = cone = 0.0
    else:
        band = metrics.prognostic_horizon(times - onset, est, life, alpha=alpha, bounds="eol",
                                          stay=True)
        cone = metrics.prognostic_horizon(times, est, t_eol, alpha=alpha, bounds="relative",
                                          stay=True)
    span = t_eol - det if det is not None and t_eol > det else math.nan
    return {"ph": band / life, "ph_flights": band,
            "ph_from_detection": band / span if math.isfinite(span) else 0.0,
            "ph_cone": cone / life, "ph_cone_flights": cone,
            "ph_cone_from_detection": cone / span if math.isfinite(span) else 0.0}


def _quantile_bound(doc: Mapping[str, Any] | None, level: float) -> float:
    """Quantile ``level`` of an RUL document as a bound: +inf beyond the prediction horizon,
    nan without a distribution or without that level."""
    if not doc:
        return math.nan
    levels = [float(q) for q, _ in doc.get("quantiles") or ()]
    if not any(math.isclose(q, level) for q in levels):
        return math.nan
    v = rul_quantile(doc, level)
    return math.inf if v is None else v


def _no_calibration() -> dict[str, Any]:
    return {"n": 0, "in_50": 0, "in_90": 0, "width_50_sum": 0.0, "n_width_50": 0,
            "width_90_sum": 0.0, "n_width_90": 0}


def _widths(docs: Sequence[Mapping[str, Any] | None], tail: float, name: str
            ) -> dict[str, Any]:
    """Sum and count of the finite widths q_(1-tail) - q_tail [flights] of the documents (a
    band open beyond the prediction horizon, or missing, has none)."""
    w = np.array([_quantile_bound(d, 1.0 - tail) - _quantile_bound(d, tail) for d in docs],
                 dtype=float)
    ok = np.isfinite(w)
    return {f"width_{name}_sum": float(w[ok].sum()), f"n_width_{name}": int(ok.sum())}


def _central_hits(docs: Sequence[Mapping[str, Any] | None], true: np.ndarray, tail: float
                  ) -> np.ndarray:
    """Whether each true RUL lies in its document's central interval [q_tail, q_(1-tail)]."""
    lo = [_quantile_bound(d, tail) for d in docs]
    hi = [_quantile_bound(d, 1.0 - tail) for d in docs]
    return metrics.interval_hits(true, lo, hi)


#: headline figures also reported with the most probable RUL as point estimate
_MOST_PROBABLE_KEYS = ("ph", "ph_cone", "ra")


def summarise_prognosis(traces: Sequence[Mapping[str, Any]], *, alpha: float = ALPHA,
                        lam: float = LAMBDA, point_estimate: str = POINT_ESTIMATE
                        ) -> dict[str, Any]:
    """Per progressive mode: per-pattern metrics and their averages with bootstrap intervals
    over the mode's patterns (PH of an undetected pattern counts as 0, alpha-lambda as a
    fail; RA, CRA and convergence are averaged over the patterns that have predictions),
    the calibration of the RUL distributions over all their selected predictions, and the
    headline figures with the most probable RUL as point estimate (``most_probable``)."""
    out: dict[str, Any] = {}
    for mode in PROGRESSIVE:
        rows = [t for t in traces if t["mode"] == mode and t["failure"] is not None]
        if not rows:
            continue
        pats = [pattern_prognosis(t, alpha=alpha, lam=lam, point_estimate=point_estimate)
                for t in rows]
        alts = [pattern_prognosis(t, alpha=alpha, lam=lam, point_estimate="mode")
                for t in rows]
        for p, a in zip(pats, alts, strict=True):
            p["most_probable"] = {k: a[k] for k in _MOST_PROBABLE_KEYS}
        out[mode] = _mode_prognosis(mode, pats, resamples(len(pats)))
    return out


def _mode_prognosis(mode: str, pats: Sequence[dict[str, Any]], idx: np.ndarray
                    ) -> dict[str, Any]:
    """One mode's averages of its patterns' metrics, each with its bootstrap interval."""
    ras = [p["ra"] for p in pats if p["ra"] is not None]
    r: dict[str, Any] = {}
    r.update(mean_ci("ph", [p["ph"] for p in pats], idx))
    r.update(mean_ci("ph_cone", [p["ph_cone"] for p in pats], idx))
    r.update(mean_ci("ph_from_detection", [p["ph_from_detection"] for p in pats], idx))
    r.update(mean_ci("ra", [nan_if_none(p["ra"]) for p in pats], idx, scale=100.0))
    r.update(mean_ci("ra_fraction", [nan_if_none(p["ra"]) for p in pats], idx))
    r["ra_median_pattern"] = 100.0 * float(np.median(ras)) if ras else None
    r.update(mean_ci("alpha_lambda", [float(p["alpha_lambda"]) for p in pats], idx))
    r.update(mean_ci("cra", [nan_if_none(p["cra"]) for p in pats], idx))
    r.update(mean_ci("convergence", [nan_if_none(p["convergence"]) for p in pats], idx))
    r["calibration"] = _calibration([p["calibration"] for p in pats], idx)
    mp: dict[str, Any] = {"point_estimate": "mode"}
    for key in _MOST_PROBABLE_KEYS:
        vals = [nan_if_none(p["most_probable"][key]) for p in pats]
        mp.update(mean_ci(key, vals, idx, scale=100.0 if key == "ra" else 1.0))
    r["most_probable"] = mp
    r["n_patterns"] = len(pats)
    r["n_with_predictions"] = sum(1 for p in pats if p["predictions"])
    r["paper"] = {"ph": PAPER_TABLE2[mode][0], "ra": PAPER_TABLE2[mode][1]}
    r["patterns"] = list(pats)
    return r


def _calibration(counts: Sequence[Mapping[str, int]], idx: np.ndarray) -> dict[str, Any]:
    """Share of the predictions whose central 50 / 90 % RUL interval holds the true RUL, and
    the mean width of those intervals [flights] (bands open beyond the horizon left out),
    pooled over the patterns' predictions and resampled by pattern."""
    n = np.array([c["n"] for c in counts], dtype=float)
    out: dict[str, Any] = {"n_predictions": int(n.sum())}
    for key, hits in (("central_50", "in_50"), ("central_90", "in_90")):
        h = np.array([c[hits] for c in counts], dtype=float)
        rate = np.divide(h, n, out=np.full_like(h, np.nan), where=n > 0)
        out.update(mean_ci(key, rate, idx, weights=n))
    for level in ("50", "90"):
        nw = np.array([c.get(f"n_width_{level}", 0) for c in counts], dtype=float)
        ws = np.array([c.get(f"width_{level}_sum", 0.0) for c in counts], dtype=float)
        mean_w = np.divide(ws, nw, out=np.full_like(ws, np.nan), where=nw > 0)
        out.update(mean_ci(f"width_{level}_flights", mean_w, idx, weights=nw))
    return out
