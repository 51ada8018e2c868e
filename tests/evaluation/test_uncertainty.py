"""Figures with their uncertainty (issue 22, item 4): Saxena's horizon beside the cone's,
bootstrap intervals over patterns, calibration of the RUL distributions, summary.json."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from server.evaluation.cli import write_outputs
from server.evaluation.scoring import (
    classification_summary,
    pattern_prognosis,
    summarise_detection,
    summarise_prognosis,
    summarise_sensors,
)
from server.evaluation.summary import summary_document
from server.phm import metrics
from server.phm.prognosis import RulDistribution
from tests.evaluation.test_evaluation import _flight, _progressive, _trace

_Z25, _Z05 = 0.6744897501960817, 1.6448536269514722  # standard normal quantiles


# ----------------------------------------------------------------------------------------------
# Saxena's horizon and the cone's


def test_saxena_and_cone_horizons_differ_as_computed_by_hand() -> None:
    # onset 80, failure 300: life 220, Saxena's band +-0.2 x 220 = +-44 flights
    onset, t_eol = 80, 300
    # predictions at 100, 120, ..., 280 (detection at 100): true RUL 200, 180, ..., 20
    off = {100: 30.0, 120: 50.0, **{i: 30.0 for i in range(140, 260, 20)}, 260: 0.0, 280: 0.0}
    fl = [_flight(i, t_eol=t_eol, alarm=i >= 100, probs={"MTWEAR": 1.0} if i >= 100 else None,
                  q50=(t_eol - i + off[i]) if i in off else None, new=i == 100, mode="MTWEAR")
          for i in range(0, t_eol + 1, 10)]
    p = pattern_prognosis(_trace("S", "MTWEAR", fl, failure=t_eol, onset=onset))
    assert [q["flight"] for q in p["predictions"]] == list(range(100, 300, 20))
    # Saxena: 50 off at flight 120 is out of +-44, every later one (30 or 0 off) in -> 160
    assert p["ph_flights"] == pytest.approx(160.0)
    assert p["ph"] == pytest.approx(160.0 / 220.0)
    assert p["ph_from_detection"] == pytest.approx(160.0 / 200.0)
    # cone: 30 off is out of +-20 % once the true RUL is below 150; only 260 and 280 (exact)
    # stay -> 40
    assert p["ph_cone_flights"] == pytest.approx(40.0)
    assert p["ph_cone"] == pytest.approx(40.0 / 220.0)
    assert p["ph_cone_from_detection"] == pytest.approx(40.0 / 200.0)
    s = summarise_prognosis([_trace("S", "MTWEAR", fl, failure=t_eol, onset=onset)])["MTWEAR"]
    assert s["ph"] == pytest.approx(160.0 / 220.0) and s["ph_cone"] == pytest.approx(40 / 220)


# ----------------------------------------------------------------------------------------------
# bootstrap interval of a mean over clusters


def test_bootstrap_interval_brackets_the_mean_and_is_reproducible() -> None:
    v = np.random.default_rng(1).normal(0.5, 0.2, size=30)
    lo, hi = metrics.bootstrap_mean_interval(v, seed=7)
    assert lo < v.mean() < hi
    # the 90 % interval of a mean of 30 values of std 0.2: about +-1.645 x 0.2 / sqrt(30)
    assert hi - lo == pytest.approx(2 * 1.645 * v.std() / np.sqrt(30), rel=0.2)
    assert metrics.bootstrap_mean_interval(v, seed=7) == (lo, hi)
    assert metrics.bootstrap_mean_interval(v, seed=8) != (lo, hi)
    idx = metrics.bootstrap_indices(30, n_boot=2000, seed=7)
    assert idx.shape == (2000, 30)
    assert metrics.bootstrap_mean_interval(v, indices=idx) == (lo, hi)


def test_bootstrap_interval_is_degenerate_for_one_cluster_and_none_without() -> None:
    assert metrics.bootstrap_mean_interval([0.37]) == (0.37, 0.37)
    assert metrics.bootstrap_mean_interval([0.37, np.nan]) == (0.37, 0.37)
    assert metrics.bootstrap_mean_interval([]) is None
    assert metrics.bootstrap_mean_interval([np.nan, np.nan]) is None


def test_bootstrap_interval_narrows_as_patterns_grow() -> None:
    rng = np.random.default_rng(3)
    widths = {}
    for n in (8, 200):
        lo, hi = metrics.bootstrap_mean_interval(rng.uniform(0.0, 1.0, size=n), seed=0)
        widths[n] = hi - lo
    # the width goes as 1 / sqrt(n): 200 patterns about 5 times narrower than 8
    assert widths[200] < 0.4 * widths[8]


def test_cluster_bootstrap_of_a_rate_resamples_clusters() -> None:
    # false alarms per flight: 3 patterns of 10, 100 and 1000 flights
    events = np.array([1.0, 0.0, 2.0])
    flights = np.array([10.0, 100.0, 1000.0])
    lo, hi = metrics.bootstrap_mean_interval(events / flights, weights=flights)
    pooled = events.sum() / flights.sum()
    assert lo <= pooled <= hi
    # the most a resample can give: the 10-flight pattern alone (0.1), the least: 0
    assert 0.0 <= lo and hi <= 0.1


def test_summaries_carry_intervals_degenerate_for_one_pattern() -> None:
    good = _progressive({i: 100.0 - i for i in range(20, 100, 10)})
    s = summarise_prognosis([good])["MTWEAR"]
    for key in ("ph", "ph_cone", "ph_from_detection", "alpha_lambda", "cra"):
        assert s[f"{key}_ci"] == [pytest.approx(s[key])] * 2, key
    assert s["ra_ci"] == [pytest.approx(100.0)] * 2
    assert s["convergence_ci"] == [pytest.approx(s["convergence"])] * 2
    assert s["most_probable"]["ra_ci"] == [pytest.approx(85.0)] * 2
    det = summarise_detection([good])["per_mode"]["MTWEAR"]
    assert det["rate_ci"] == [1.0, 1.0] and det["pct_life_mean_ci"] == [20.0, 20.0]
    cls = classification_summary([good], ["MTEL", "MTWEAR"])["at_first_alarm"]
    assert cls["accuracy_ci"] == [1.0, 1.0]
    assert cls["per_class"]["MTWEAR"]["recall_ci"] == [1.0, 1.0]


def test_summary_intervals_over_many_patterns_bracket_and_narrow() -> None:
    def patterns(n: int, seed: int) -> list[dict[str, Any]]:
        rng = np.random.default_rng(seed)
        # a pattern is either right (median on the truth) or 50 % high: PH 0.8 or 0
        return [_progressive({i: (1.5 if bad else 1.0) * (100.0 - i)
                              for i in range(20, 100, 10)})
                for bad in rng.random(n) < 0.5]

    few = summarise_prognosis(patterns(8, 0))["MTWEAR"]
    many = summarise_prognosis(patterns(200, 0))["MTWEAR"]
    for s in (few, many):
        lo, hi = s["ph_ci"]
        assert lo <= s["ph"] <= hi
    assert many["ph_ci"][1] - many["ph_ci"][0] < 0.4 * (few["ph_ci"][1] - few["ph_ci"][0])
    assert summarise_prognosis(patterns(8, 0))["MTWEAR"]["ph_ci"] == few["ph_ci"]


def test_false_alarm_rate_interval_over_patterns() -> None:
    def healthy(pid: str, n: int, alarm_at: int | None) -> dict[str, Any]:
        return _trace(pid, "healthy", [_flight(i, t_eol=None, alarm=False, probs=None,
                                               new=i == alarm_at) for i in range(n)],
                      failure=None, position=None)

    traces = [healthy("A", 20, 3), healthy("B", 20, None), healthy("C", 40, None),
              healthy("D", 20, 5)]
    fa = summarise_detection(traces)["false_alarms"]
    assert fa["rate_per_flight"] == pytest.approx(2 / 100)
    lo, hi = fa["rate_per_flight_ci"]
    assert lo <= 2 / 100 <= hi and hi <= 2 / 40 and fa["clusters"] == 4


# ----------------------------------------------------------------------------------------------
# calibration


def _normal_doc(index: int, centre: float, sigma: float) -> dict[str, Any]:
    """An RUL document with the quantiles of N(centre, sigma)."""
    q = {0.05: centre - _Z05 * sigma, 0.25: centre - _Z25 * sigma, 0.5: centre,
         0.75: centre + _Z25 * sigma, 0.95: centre + _Z05 * sigma}
    return RulDistribution(
        flight_index=index, quantiles=q, mean=centre, p_fail_within={}, p_beyond_horizon=0.0,
        histogram_edges=np.array([0.0, 1.0]), histogram_mass=np.array([1.0]),
        severity_mean=0.5, severity_std=0.0, most_probable=centre).to_dict()


def _calibration_traces(n: int, *, bias: float, sigma: float = 10.0, seed: int = 0
                        ) -> list[dict[str, Any]]:
    """``n`` patterns (failure 1000, detected at 200: 10 predictions each) whose true RUL is
    drawn from each prediction's N(centre, sigma), shifted by ``bias`` sigmas."""
    rng = np.random.default_rng(seed)
    out = []
    for k in range(n):
        tr = _progressive({}, detect=200, t_eol=1000)
        tr["id"] = f"C{k}"
        for f in tr["flights"]:
            if f["index"] >= 200 and f["index"] < 1000:
                true = 1000.0 - f["index"]
                centre = true - sigma * (rng.standard_normal() + bias)
                f["rul"] = _normal_doc(f["index"], centre, sigma)
        out.append(tr)
    return out


def test_calibrated_rul_distributions_cover_50_and_90_percent() -> None:
    cal = summarise_prognosis(_calibration_traces(100, bias=0.0))["MTWEAR"]["calibration"]
    assert cal["n_predictions"] == 1000
    assert cal["central_50"] == pytest.approx(0.5, abs=0.05)
    assert cal["central_90"] == pytest.approx(0.9, abs=0.03)
    for key in ("central_50", "central_90"):
        lo, hi = cal[f"{key}_ci"]
        assert lo <= cal[key] <= hi and hi - lo < 0.1
    # the bands of N(centre, 10): 2 x 0.674 x 10 and 2 x 1.645 x 10 flights wide
    assert cal["width_50_flights"] == pytest.approx(2 * _Z25 * 10.0)
    assert cal["width_90_flights"] == pytest.approx(2 * _Z05 * 10.0)
    assert cal["width_90_flights_ci"] == pytest.approx([2 * _Z05 * 10.0] * 2)  # all alike


def test_biased_rul_distributions_cover_much_less() -> None:
    # the truth 2 sigmas above the centre: P(|z + 2| < 0.674) = 0.09, P(|z + 2| < 1.645) = 0.36
    cal = summarise_prognosis(_calibration_traces(100, bias=2.0))["MTWEAR"]["calibration"]
    assert cal["central_50"] < 0.2 and cal["central_90"] < 0.5


def test_a_prediction_without_distribution_misses_both_intervals() -> None:
    tr = _calibration_traces(1, bias=0.0)[0]
    for f in tr["flights"]:  # centred on the truth: inside both intervals
        if f["rul"]:
            f["rul"] = _normal_doc(f["index"], 1000.0 - f["index"], 10.0)
    by = {f["index"]: f for f in tr["flights"]}
    by[280]["rul"] = None  # the second prediction (classified as a mode without prognosis)
    p = pattern_prognosis(tr)
    assert {k: p["calibration"][k] for k in ("n", "in_50", "in_90", "n_width_90")} == {
        "n": 10, "in_50": 9, "in_90": 9, "n_width_90": 9}  # no distribution: no width
    assert [q["in_90"] for q in p["predictions"]][:2] == [True, False]
    cal = summarise_prognosis([tr])["MTWEAR"]["calibration"]
    assert cal["central_50"] == pytest.approx(0.9) and cal["central_50_ci"] == [0.9, 0.9]


def test_interval_coverage_counts_missing_bounds_as_misses() -> None:
    assert metrics.interval_coverage([1.0, 2.0, 3.0, 4.0], [0.0, 2.5, np.nan, 3.0],
                                     [2.0, 3.0, 5.0, np.inf]) == pytest.approx(0.5)
    assert np.isnan(metrics.interval_coverage([], [], []))


# ----------------------------------------------------------------------------------------------
# summary.json


def _keys(obj: Any) -> set[str]:
    if isinstance(obj, dict):
        return set(obj) | set().union(*(_keys(v) for v in obj.values()))
    if isinstance(obj, list):
        return set().union(*(_keys(v) for v in obj)) if obj else set()
    return set()


def _lists_under(obj: Any, names: set[str]) -> bool:
    """Whether some key in ``names`` holds a list, anywhere in ``obj``."""
    if isinstance(obj, dict):
        return any((k in names and isinstance(v, list)) or _lists_under(v, names)
                   for k, v in obj.items())
    if isinstance(obj, list):
        return any(_lists_under(v, names) for v in obj)
    return False


def test_summary_json_has_the_figures_but_no_per_flight_data(tmp_path: Path) -> None:
    traces = _calibration_traces(40, bias=0.0)
    traces += [_trace(f"H{k}", "healthy", [_flight(i, t_eol=None, alarm=False, probs=None)
                                           for i in range(30)], failure=None, position=None)
               for k in range(10)]
    result = {
        "format": "ema-evaluation/1",
        "campaign": {"dir": "x", "kind": "verification", "seed": 0, "scale": "quick",
                     "render_every": 10, "patterns": len(traces), "flights": 4000},
        "model": {"format": "ema-phm-model/5", "sha256": "0" * 64, "source": "test",
                  "measurement": {"big": list(range(1000))}},
        "settings": {"alpha": 0.2},
        "detection": summarise_detection(traces),
        "classification": classification_summary(traces, ["MTEL", "MTWEAR"]),
        "prognosis": summarise_prognosis(traces),
        "sensors": summarise_sensors(traces),
        "timing": {"pf_update_ms": 0.1, "paper": {}},
        "patterns": traces,
    }
    written = write_outputs(result, tmp_path / "out", latest=None)
    path = tmp_path / "out" / "summary.json"
    assert path in written
    text = path.read_text()
    assert len(text.encode()) < 50_000
    assert len(text) < (tmp_path / "out" / "evaluation.json").stat().st_size / 20
    doc = json.loads(text)
    assert list(doc) == ["format", "evaluation_format", "created_at", "campaign", "model",
                         "settings", "detection", "classification", "prognosis", "sensors",
                         "timing", "wall_s"]
    # no trace (per-flight keys), no prediction list, no pattern list (counts only)
    assert not _keys(doc) & {"predictions", "instants", "rul", "true_rul", "severity_norm",
                             "new_alarms", "probs", "q05", "measurement"}
    assert not _lists_under(doc, {"patterns", "flights"})
    mine = doc["prognosis"]["MTWEAR"]
    assert mine["ph"] == result["prognosis"]["MTWEAR"]["ph"]
    assert mine["ph_ci"] == result["prognosis"]["MTWEAR"]["ph_ci"]
    assert set(mine["calibration"]) == {"n_predictions", "central_50", "central_50_ci",
                                        "central_90", "central_90_ci", "width_50_flights",
                                        "width_50_flights_ci", "width_90_flights",
                                        "width_90_flights_ci"}
    assert doc["model"] == {"format": "ema-phm-model/5", "sha256": "0" * 64, "source": "test"}
    # stable: the same result gives the same bytes
    assert json.dumps(summary_document(result), indent=1) == json.dumps(
        summary_document(json.loads((tmp_path / "out" / "evaluation.json").read_text())),
        indent=1)
