"""Dashboard figures from plain data, without a browser."""

from __future__ import annotations

import json

import plotly.graph_objects as go

from server.web import figures
from tests.web.seed import CONFUSION, rul_document


def _prognoses(n: int = 10, severity_std: float = 0.02) -> list[dict]:
    out = []
    for i in range(1, n + 1):
        med = 50.0 - 2 * i
        out.append({"flight_index": i, "fault_mode": "DMD", "distribution": rul_document(
            i, med, 0.05 * i, severity_std, [0.0, 10.0, 20.0, 30.0], [0.2, 0.5, 0.3],
            spread=(0.6, 0.8, 1.2, 1.4))})
    return out


def _names(fig: go.Figure) -> list[str]:
    return [t.name for t in fig.data]


def test_rul_cone_has_median_band_and_truth_cone() -> None:
    progs = _prognoses()
    truth = {p["flight_index"]: 45.0 - 2 * p["flight_index"] for p in progs}
    fig = figures.rul_cone(progs, truth, alpha=0.2)
    names = _names(fig)
    assert "median RUL" in names and "5-95 % band" in names
    assert "true RUL" in names and "true RUL ±20 %" in names
    median = fig.data[names.index("median RUL")]
    assert list(median.x) == list(range(1, 11))
    assert median.y[0] == 48.0
    band = fig.data[names.index("5-95 % band")]
    assert len(band.x) == 20 and band.fill == "toself"
    assert max(band.y) == 48.0 * 1.4 and min(band.y) == 30.0 * 0.6
    cone = fig.data[names.index("true RUL ±20 %")]
    assert cone.y[0] == 43.0 * 1.2 and cone.y[-1] == 43.0 * 0.8


def test_rul_cone_without_truth_has_no_truth_cone_and_survives_empty() -> None:
    assert "true RUL" not in _names(figures.rul_cone(_prognoses(), None))
    empty = figures.rul_cone([], None)
    assert _names(empty) == ["median RUL"] and len(empty.data[0].x) == 0


def test_rul_histogram_bars_at_bin_centres_and_median_line() -> None:
    fig = figures.rul_histogram(_prognoses()[-1])
    bars = fig.data[0]
    assert list(bars.x) == [5.0, 15.0, 25.0] and list(bars.y) == [0.2, 0.5, 0.3]
    assert fig.data[1].x[0] == 30.0
    assert len(figures.rul_histogram(None).data) == 0


def test_severity_band_is_mean_plus_minus_two_std_clipped_at_zero() -> None:
    progs = _prognoses(3, severity_std=0.03)
    fig = figures.severity_band(progs)
    band = fig.data[0]
    assert band.y[0] == 0.05 + 0.06            # upper, first flight
    assert band.y[-1] == 0.0 and band.y[-2] > 0  # lower, clipped at 0 for flight 1
    assert "failure threshold" in _names(fig)


def test_feature_trends_band_threshold_and_one_trace_per_feature() -> None:
    records = [{"flight_index": i, "scores": {"z": {"WL1.F_DMD": 0.5 * i, "WL1.F_TTS": -0.1}},
                "confidence": 0.1, "alarm": False} for i in range(1, 6)]
    fig = figures.feature_trends(records, band=3.0, threshold=5.05)
    names = _names(fig)
    # each feature by its code and what it measures
    assert "WL1.F_DMD magnet flux deficit" in names
    assert "WL1.F_TTS winding-to-frame leakage" in names
    band = fig.data[0]
    assert max(band.y) == 3.0 and min(band.y) == -3.0
    thr = [t for t in fig.data if (t.name or "").startswith("alarm threshold")]
    assert sorted(t.y[0] for t in thr) == [-5.05, 5.05]


def test_confidence_and_class_probabilities() -> None:
    records = [{"flight_index": i, "confidence": 0.1 * i, "alarm": i > 8,
                "class_probabilities": {"DMD": 0.9, "TTS": 0.1} if i > 8 else None}
               for i in range(1, 11)]
    conf = figures.detection_confidence(records, alarm_level=0.98)
    assert list(conf.data[0].y)[:2] == [0.1, 0.2]
    assert list(conf.data[1].x) == [9, 10]  # in-alarm markers
    classes = figures.class_probabilities(records)
    assert _names(classes) == ["DMD", "TTS"] and list(classes.data[0].x) == [9, 10]


def test_confusion_matrix_heatmap_of_rates_with_counts() -> None:
    fig = figures.confusion_matrix(CONFUSION)
    heat = fig.data[0]
    assert heat.type == "heatmap"
    assert list(heat.x) == CONFUSION["classes"] and list(heat.y) == CONFUSION["classes"]
    assert heat.z[0][0] == 0.9 and heat.text[0][0].startswith("9<br>90")
    assert "accuracy" in fig.layout.title.subtitle.text


def test_figure_json_is_safe_inside_a_script_element() -> None:
    fig = figures.rul_cone(_prognoses(2), None)
    fig.update_layout(title="</script><b>x</b> & y")
    text = figures.figure_json(fig)
    assert "</" not in text and "<" not in text and "&" not in text
    assert json.loads(text)["layout"]["title"]["text"] == "</script><b>x</b> & y"


def test_an_empty_plot_says_no_data_yet_instead_of_bare_axes() -> None:
    for fig in (figures.rul_cone([], None), figures.feature_trends([], band=3.0, threshold=5.05),
                figures.detection_confidence([], alarm_level=0.98)):
        assert [a.text for a in fig.layout.annotations] == ["no data yet"]
        assert fig.layout.xaxis.visible is False and fig.layout.yaxis.visible is False
    full = figures.detection_confidence([{"flight_index": 1, "confidence": 0.2, "alarm": False}],
                                        alarm_level=0.98)
    assert not full.layout.annotations and full.layout.xaxis.visible is not False
