"""Aggregation logic of the evaluation (server.evaluation) on hand-built traces (no campaign)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from server.evaluation.cli import write_outputs
from server.evaluation.scoring import (
    classification_summary,
    confusion,
    pattern_prognosis,
    prediction_instants,
    select_prediction_flights,
    summarise_detection,
    summarise_prognosis,
)
from server.phm.prognosis import RulDistribution


def _flight(index: int, *, t_eol: float | None, alarm: bool, probs: dict[str, float] | None,
            q50: float | None = None, new: bool = False, mode: str | None = None
            ) -> dict[str, Any]:
    # the most probable RUL of these right-skewed test distributions: 0.85 x the median
    rul = None if q50 is None else RulDistribution(
        flight_index=index, quantiles={0.05: 0.5 * q50, 0.5: q50, 0.95: 1.5 * q50}, mean=q50,
        p_fail_within={}, p_beyond_horizon=0.0, histogram_edges=np.array([0.0, 1.0]),
        histogram_mass=np.array([1.0]), severity_mean=0.5, severity_std=0.0,
        most_probable=0.85 * q50).to_dict()
    return {"index": index, "severity_norm": 0.0,
            "true_rul": None if t_eol is None else t_eol - index,
            "alarms": ["WL1"] if alarm else [], "new_alarms": ["WL1"] if new else [],
            "alarm": alarm, "probs": probs, "fault_mode": mode if alarm else None, "rul": rul}


def _trace(pid: str, mode: str, flights: list[dict[str, Any]], *, failure: int | None,
           onset: int = 0, position: str | None = "WL1") -> dict[str, Any]:
    return {"id": pid, "aircraft": "A", "mode": mode, "position": position, "onset": onset,
            "failure": failure, "seed": 0, "horizon": 2000.0, "flights": flights}


def _progressive(rul_of: dict[int, float], *, detect: int = 20, t_eol: int = 100
                 ) -> dict[str, Any]:
    p = {"MTWEAR": 0.9, "MTEL": 0.1}
    fl = [_flight(i, t_eol=t_eol, alarm=i >= detect, probs=p if i >= detect else None,
                  q50=rul_of.get(i), new=i == detect, mode="MTWEAR")
          for i in range(0, t_eol + 1, 10)]
    return _trace("P", "MTWEAR", fl, failure=t_eol)


def test_prediction_instants_equally_spaced_from_detection_to_eol() -> None:
    inst = prediction_instants(20.0, 120.0)
    assert inst.shape == (10,)
    np.testing.assert_allclose(inst, 20.0 + 10.0 * np.arange(10))
    assert prediction_instants(50.0, 50.0).size == 0


def test_nearest_flights_merge_duplicates_and_prefer_earlier_on_ties() -> None:
    inst = prediction_instants(20.0, 120.0)  # 20, 30, ..., 110
    chosen = select_prediction_flights([20, 40, 60, 80, 100], inst)
    # 30 ties between 20 and 40 -> 20; 110 -> 100
    np.testing.assert_array_equal(chosen, [20, 40, 60, 80, 100])
    assert select_prediction_flights([], inst).size == 0


def test_ph_and_ra_match_hand_computation() -> None:
    t_eol = 100
    # predictions at 20..90: true RUL 80..10; first two off by 50 %, then within 10 %
    rul = {20: 120.0, 30: 105.0, 40: 66.0, 50: 45.0, 60: 44.0, 70: 27.0, 80: 21.0, 90: 9.0}
    p = pattern_prognosis(_progressive(rul, t_eol=t_eol))
    assert [q["flight"] for q in p["predictions"]] == [20, 30, 40, 50, 60, 70, 80, 90]
    # within +-20 % from flight 40 on, and stays -> cone PH = 100 - 40 = 60 flights, life 100
    assert p["ph_cone_flights"] == pytest.approx(60.0)
    assert p["ph_cone"] == pytest.approx(0.6)
    assert p["ph_cone_from_detection"] == pytest.approx(60.0 / 80.0)
    # Saxena's constant band, +-0.2 x life = +-20 flights: 120 vs 80 and 105 vs 70 are out,
    # 66 vs 60 on are in -> the same 60 flights here
    assert p["ph"] == pytest.approx(0.6) and p["ph_flights"] == pytest.approx(60.0)
    assert p["ph_from_detection"] == pytest.approx(60.0 / 80.0)
    true = np.array([80, 70, 60, 50, 40, 30, 20, 10], dtype=float)
    pred = np.array([rul[i] for i in range(20, 100, 10)])
    assert p["ra"] == pytest.approx(float(np.mean(1 - np.abs(pred - true) / true)))
    # alpha-lambda at lambda 0.5: t = 20 + 0.5 * 80 = 60, prediction 44 vs 40 -> inside
    assert p["alpha_lambda"] is True
    w = np.arange(1, 9, dtype=float)
    assert p["cra"] == pytest.approx(float(np.dot(w, 1 - np.abs(pred - true) / true) / w.sum()))
    assert p["convergence"] is not None and p["convergence"] > 0


def test_ph_requires_staying_in_the_cone_and_missing_predictions_count_outside() -> None:
    rul = {20: 80.0, 30: 70.0, 40: 60.0, 50: 50.0, 60: 40.0, 70: 30.0, 80: 40.0, 90: 10.0}
    p = pattern_prognosis(_progressive(rul))
    assert p["ph_cone_flights"] == pytest.approx(10.0)  # only the last one stays inside
    # the constant band (+-0.2 x life = +-20 flights) keeps 40 vs 20 at flight 80 (on its
    # edge): every prediction from detection on is inside -> 80 flights
    assert p["ph"] == pytest.approx(0.8)
    p_b = pattern_prognosis(_progressive({**rul, 80: 45.0}))  # 25 off: outside both
    assert p_b["ph_cone_flights"] == pytest.approx(10.0) and p_b["ph"] == pytest.approx(0.1)
    del rul[90]
    p = pattern_prognosis(_progressive(rul))
    assert p["ph"] == 0.0 and p["ph_cone"] == 0.0
    assert len(p["predictions"]) == 8 and p["predictions"][-1]["point"] is None
    assert p["ra"] is not None  # averaged over the 7 predictions that exist


def test_the_most_probable_rul_can_be_scored_instead_of_the_median() -> None:
    # medians exactly on the truth; the modes 15 % low, still inside the cone
    rul = {i: 100.0 - i for i in range(20, 100, 10)}
    median = pattern_prognosis(_progressive(rul))
    mode = pattern_prognosis(_progressive(rul), point_estimate="mode")
    assert median["ra"] == pytest.approx(1.0) and mode["ra"] == pytest.approx(0.85)
    assert median["ph_cone"] == pytest.approx(0.8) and mode["ph_cone"] == pytest.approx(0.8)
    # medians 30 % high: outside the cone; their modes (1.105 x truth) inside
    rul = {i: 1.3 * (100.0 - i) for i in range(20, 100, 10)}
    assert pattern_prognosis(_progressive(rul))["ph_cone"] == 0.0
    mode = pattern_prognosis(_progressive(rul), point_estimate="mode")
    assert mode["ph_cone"] == pytest.approx(0.8) and mode["ra"] == pytest.approx(1 - 0.105)
    # reported beside the median in the mode's summary
    mp = summarise_prognosis([_progressive(rul)])["MTWEAR"]["most_probable"]
    assert mp["ph_cone"] == pytest.approx(0.8) and mp["ra"] == pytest.approx(89.5)
    assert mp["ph_cone_ci"] == [pytest.approx(0.8)] * 2
    with pytest.raises(ValueError, match="point_estimate"):
        pattern_prognosis(_progressive(rul), point_estimate="mean")


def test_undetected_pattern_has_zero_horizon_and_counts_in_mode_average() -> None:
    fl = [_flight(i, t_eol=100, alarm=False, probs=None) for i in range(0, 101, 10)]
    undetected = _trace("U", "MTWEAR", fl, failure=100)
    good = _progressive({i: 100.0 - i for i in range(20, 100, 10)})
    summary = summarise_prognosis([undetected, good])["MTWEAR"]
    assert summary["n_patterns"] == 2 and summary["n_with_predictions"] == 1
    assert summary["ph"] == pytest.approx((0.0 + 0.8) / 2)
    assert summary["ra"] == pytest.approx(100.0)
    assert summary["ra_fraction"] == pytest.approx(1.0)


def test_detection_and_false_alarms() -> None:
    healthy = _trace("H", "healthy", [_flight(i, t_eol=None, alarm=i >= 3, probs=None,
                                              new=i == 3) for i in range(5)],
                     failure=None, position=None)
    good = _progressive({}, detect=30)
    det = summarise_detection([healthy, good])
    fa = det["false_alarms"]
    assert fa["healthy_patterns"] == 1 and fa["healthy_patterns_with_alarm"] == 1
    assert fa["false_alarm_events"] == 1 and fa["healthy_flights"] == 5
    m = det["per_mode"]["MTWEAR"]
    assert m["detected"] == 1 and m["pct_life_mean"] == pytest.approx(30.0)
    assert m["flights_after_onset_max"] == pytest.approx(30.0)


def test_confusion_matrix_and_rates() -> None:
    c = confusion(["A", "A", "B", "B"], ["A", "B", "B", "undetected"], ["A", "B"])
    assert c["columns"] == ["A", "B", "undetected"]
    assert c["matrix"] == [[1, 1, 0], [0, 1, 1]]
    assert c["accuracy"] == pytest.approx(0.5)
    assert c["per_class"]["A"]["recall"] == pytest.approx(0.5)
    assert c["per_class"]["B"]["precision"] == pytest.approx(0.5)
    t = _progressive({})
    cls = classification_summary([t], ["MTEL", "MTWEAR"])
    assert cls["at_first_alarm"]["matrix"] == [[0, 1, 0]]


def test_outputs_and_latest_json_match_the_dashboard(tmp_path: Path) -> None:
    from server.web.data import evaluation_view

    traces = [_progressive({i: 100.0 - i for i in range(20, 100, 10)})]
    result = {
        "campaign": {"dir": "x", "kind": "verification", "seed": 0, "scale": "quick",
                     "render_every": 10, "patterns": 1, "flights": 11},
        "detection": summarise_detection(traces),
        "classification": classification_summary(traces, ["MTEL", "MTWEAR"]),
        "prognosis": summarise_prognosis(traces),
        "timing": {"pf_update_ms": 0.1, "paper": {}},
        "patterns": traces,
    }
    data = tmp_path / "data"
    written = write_outputs(result, tmp_path / "out", latest=data / "evaluation" / "latest.json")
    names = {p.name for p in written}
    assert {"evaluation.json", "summary.json", "report.html", "rul_MTWEAR.html", "summary.md",
            "latest.json"} <= names
    page = (tmp_path / "out" / "report.html").read_text()
    assert 'src="http' not in page  # no CDN: plotly.js embedded, once
    assert page.count("plotly.js v") == 1
    latest = json.loads((data / "evaluation" / "latest.json").read_text())
    assert latest["prognosis"]["MTWEAR"]["ph"] == pytest.approx(0.8)
    view = evaluation_view(data_dir=data)
    row = next(r for r in view["rows"] if r["mode"] == "MTWEAR")
    assert view["has_ours"] and row["ph"] == pytest.approx(0.8) and row["ra"] == pytest.approx(100)
    assert row["ph_cone"] == pytest.approx(0.8)
    md = (tmp_path / "out" / "summary.md").read_text()
    assert "| MTWEAR | 0.80 [0.80, 0.80] | 0.80 [0.80, 0.80] |" in md


def test_probability_calibration_compares_shown_confidence_with_accuracy() -> None:
    from server.evaluation.scoring import probability_calibration

    cal = probability_calibration(
        ["MTEL", "MTEL", "MTWEAR", "TTS"],
        [{"MTEL": 0.8, "MTWEAR": 0.2}, {"MTEL": 0.995, "MTWEAR": 0.005},
         {"MTEL": 0.6, "MTWEAR": 0.4}, None])
    assert cal["n"] == 3 and cal["at_least_99pct"] == 1
    assert cal["mean_confidence"] == pytest.approx((0.8 + 0.995 + 0.6) / 3)
    assert cal["accuracy"] == pytest.approx(2 / 3)  # the MTWEAR pattern read MTEL
    assert cal["log_loss"] == pytest.approx(-(np.log(0.8) + np.log(0.995) + np.log(0.4)) / 3)
    assert probability_calibration(["MTEL"], [None])["n"] == 0
