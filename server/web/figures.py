"""Dashboard figures: pure functions from plain data to plotly figures (no DB, no request).

Inputs are the JSON shapes the API returns (``/actuators/{id}/health`` records,
``/actuators/{id}/prognoses`` items, a model's ``metrics["confusion"]``), so the figures can be
unit-tested without a browser and reused by any page.

Conventions: the x axis of every actuator figure is the **flight index** (flights the actuator
has flown since installation, one health record per flight). Feature trends are standardised
residuals ``z`` (dimensionless, N(0, 1) on healthy flights); RUL is in flights; fault severity
is normalised (failure threshold 1.0). Colours are paired with text labels and line dashes so
nothing is told by colour alone.
"""

from __future__ import annotations

import math
import textwrap
from collections.abc import Mapping, Sequence
from typing import Any

import plotly.graph_objects as go

from server.phm.prognosis.document import rul_quantile
from server.vocabulary import FEATURE_LABELS

__all__ = [
    "figure_json",
    "feature_trends",
    "detection_confidence",
    "class_probabilities",
    "severity_band",
    "rul_cone",
    "rul_histogram",
    "confusion_matrix",
]

_TEMPLATE = "plotly_white"
#: plotly pushes the margins further where the title, the tick labels, the axis titles or the
#: legend need it (automargin): these are the least
_MARGIN = {"l": 56, "r": 16, "t": 40, "b": 16}
#: the strip at the top of a figure that plotly's mode bar (its toolbar, drawn over the
#: figure's top right corner, 25 px tall) takes: titles start below it, never under the bar
MODEBAR_PX = 28
#: the longest line of a legend entry [characters]: a longer name is wrapped, so that an entry
#: fits a phone's figure (390 px wide) whole instead of being cut at its edge
LEGEND_LINE_CHARS = 34
_PALETTE = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2",
            "#7f7f7f")


def figure_json(fig: go.Figure) -> str:
    """The figure as JSON safe to embed in ``<script type="application/json">`` (no ``</``)."""
    text = fig.to_json()
    return text.replace("<", "\\u003c").replace(">", "\\u003e").replace("&", "\\u0026")


def _finite(v: Any) -> float | None:
    try:
        f = float(v)
    except (TypeError, ValueError):
        return None
    return f if math.isfinite(f) else None


def _has_data(fig: go.Figure) -> bool:
    """Whether any trace has a finite value to show (a band alone is no data)."""
    for trace in fig.data:
        values = getattr(trace, "z", None) if trace.type == "heatmap" else trace.y
        if values is not None and any(
                v is not None and isinstance(v, int | float) and math.isfinite(v)
                for row in values for v in (row if isinstance(row, list | tuple) else [row])):
            return True
    return False


def _layout(fig: go.Figure, title: str, x: str, y: str, *, subtitle: str | None = None,
            **extra: Any) -> go.Figure:
    """The house layout. The title (and its subtitle, the detail a narrow figure would cut
    off) sits below the mode bar's strip, and pushes the plot down as far as it needs
    (``automargin``). The legend is a row under the figure, placed from the figure's bottom edge
    in pixels (``yref`` container), not at a fraction of the plot's height, which on a short
    plot put it over the x axis title; its room is pushed into the bottom margin."""
    settings: dict[str, Any] = {
        "hovermode": "x unified",
        "legend": {"orientation": "h", "xref": "container", "x": 0.01, "xanchor": "left",
                   "yref": "container", "y": 0, "yanchor": "bottom"},
        **extra}
    heading: dict[str, Any] = {"text": title, "x": 0.01, "xanchor": "left",
                               "yref": "container", "y": 1, "yanchor": "top",
                               "pad": {"t": MODEBAR_PX}, "automargin": True}
    if subtitle:
        heading["subtitle"] = {"text": subtitle}
    fig.update_layout(title=heading, template=_TEMPLATE, margin=_MARGIN,
                      xaxis={"title": {"text": x}, "automargin": True},
                      yaxis={"title": {"text": y}, "automargin": True}, **settings)
    if not _has_data(fig):
        # an empty plot says so, instead of bare default axes (-1 to 6: a negative probability)
        fig.update_layout(xaxis={"visible": False}, yaxis={"visible": False},
                          annotations=[{"text": "no data yet", "showarrow": False,
                                        "xref": "paper", "yref": "paper", "x": 0.5, "y": 0.5,
                                        "font": {"size": 16, "color": "#555"}}])
    return fig


def feature_label(name: str) -> str:
    """``"WT.F_DMD"`` -> ``"WT.F_DMD magnet flux deficit"``: the code and what it measures."""
    label = FEATURE_LABELS.get(name.split(".", 1)[-1])
    return f"{name} {label}" if label else name


def legend_name(text: str) -> str:
    """``text`` in lines of at most :data:`LEGEND_LINE_CHARS` (plotly's ``<br>``): plotly
    never wraps a legend entry itself."""
    return "<br>".join(textwrap.wrap(text, LEGEND_LINE_CHARS)) or text


def mark_station(fig: go.Figure, marks: Sequence[Mapping[str, Any]]) -> go.Figure:
    """Shade the flights flown under test-station injections or conditions (grey bands, one
    per run of flights, ``server.services.dashboard.station_marks``): what the chart shows
    there is not the aircraft's own service."""
    for m in marks:
        fig.add_vrect(x0=m["first"] - 0.5, x1=m["last"] + 0.5, fillcolor="rgba(80,80,80,0.14)",
                      line_width=0, layer="below")
    return fig


def feature_trends(records: Sequence[Mapping[str, Any]], *, band: float, threshold: float,
                   marks: Sequence[Mapping[str, Any]] = ()) -> go.Figure:
    """Standardised residual ``z`` of every monitored feature against flight index.

    The shaded band is the healthy baseline ``0 +- band``; dashed lines at ``+-threshold`` are
    the detector's single-flight alarm level (band + the 98 % one-sided quantile); grey bands
    mark the flights flown under the test station (``marks``).
    """
    fig = go.Figure()
    xs = [int(r["flight_index"]) for r in records]
    names: list[str] = sorted({n for r in records for n in (r.get("scores") or {}).get("z", {})})
    if xs:
        x0, x1 = min(xs), max(xs)
        fig.add_trace(go.Scatter(x=[x0, x1, x1, x0, x0], y=[-band, -band, band, band, -band],
                                 fill="toself", fillcolor="rgba(44,160,44,0.12)",
                                 mode="lines", line={"width": 0},
                                 name=f"healthy band (±{band:.2f})", hoverinfo="skip"))
        for sign in (1, -1):
            fig.add_trace(go.Scatter(x=[x0, x1], y=[sign * threshold] * 2, mode="lines",
                                     line={"color": "#d62728", "dash": "dash", "width": 1.5},
                                     name=f"alarm threshold (±{threshold:.2f})",
                                     showlegend=sign == 1, hoverinfo="skip"))
    for i, name in enumerate(names):
        ys = [_finite((r.get("scores") or {}).get("z", {}).get(name)) for r in records]
        fig.add_trace(go.Scatter(x=xs, y=ys, mode="lines+markers",
                                 name=legend_name(feature_label(name)), marker={"size": 4},
                                 line={"color": _PALETTE[i % len(_PALETTE)]},
                                 connectgaps=False))
    return mark_station(_layout(fig, "Feature trends (standardised residual z)",
                                "flight index", "z"), marks)


def detection_confidence(records: Sequence[Mapping[str, Any]], *, alarm_level: float
                         ) -> go.Figure:
    """Detection confidence per flight (max over features) with the alarm level (the model's
    ``alarm_confidence``)."""
    xs = [int(r["flight_index"]) for r in records]
    ys = [_finite(r.get("confidence")) for r in records]
    alarms = [(x, y) for x, y, r in zip(xs, ys, records, strict=True) if r.get("alarm")]
    fig = go.Figure([go.Scatter(x=xs, y=ys, mode="lines+markers", name="confidence",
                                marker={"size": 4}, line={"color": "#1f77b4"})])
    if alarms:
        fig.add_trace(go.Scatter(x=[a[0] for a in alarms], y=[a[1] for a in alarms],
                                 mode="markers", name="in alarm",
                                 marker={"color": "#d62728", "symbol": "x", "size": 8}))
    if xs:
        fig.add_trace(go.Scatter(x=[min(xs), max(xs)], y=[alarm_level] * 2, mode="lines",
                                 name=f"alarm level {alarm_level:g}",
                                 line={"color": "#d62728", "dash": "dash"}))
    return _layout(fig, "Detection confidence", "flight index", "confidence",
                   yaxis_range=[0, 1.05])


def class_probabilities(records: Sequence[Mapping[str, Any]]) -> go.Figure:
    """Fault-class probabilities per flight, stacked (only flights after an alarm have them)."""
    rows = [r for r in records if r.get("class_probabilities")]
    classes = sorted({c for r in rows for c in r["class_probabilities"]})
    xs = [int(r["flight_index"]) for r in rows]
    fig = go.Figure()
    for i, c in enumerate(classes):
        fig.add_trace(go.Scatter(x=xs, y=[_finite(r["class_probabilities"].get(c)) or 0.0
                                          for r in rows],
                                 mode="lines", stackgroup="p", name=c,
                                 line={"color": _PALETTE[i % len(_PALETTE)]}))
    return _layout(fig, "Fault-class probabilities", "flight index", "probability",
                   yaxis_range=[0, 1])


def severity_band(prognoses: Sequence[Mapping[str, Any]]) -> go.Figure:
    """Estimated normalised fault severity with the particle band (mean +- 2 std)."""
    xs = [int(p["flight_index"]) for p in prognoses]
    mean = [float(p["distribution"]["severity_mean"]) for p in prognoses]
    std = [float(p["distribution"]["severity_std"]) for p in prognoses]
    hi = [m + 2 * s for m, s in zip(mean, std, strict=True)]
    lo = [max(m - 2 * s, 0.0) for m, s in zip(mean, std, strict=True)]
    fig = go.Figure()
    if xs:
        fig.add_trace(go.Scatter(x=xs + xs[::-1], y=hi + lo[::-1], fill="toself",
                                 fillcolor="rgba(148,103,189,0.2)", line={"width": 0},
                                 mode="lines", name="mean ± 2 std", hoverinfo="skip"))
        fig.add_trace(go.Scatter(x=[min(xs), max(xs)], y=[1.0, 1.0], mode="lines",
                                 name="failure threshold",
                                 line={"color": "#d62728", "dash": "dash"}))
    fig.add_trace(go.Scatter(x=xs, y=mean, mode="lines+markers", name="severity mean",
                             marker={"size": 4}, line={"color": "#9467bd"}))
    return _layout(fig, "Fault severity estimate", "flight index", "normalised severity")


def rul_cone(prognoses: Sequence[Mapping[str, Any]],
             truth: Mapping[int, float] | None = None, *, alpha: float = 0.2,
             planned: bool = False) -> go.Figure:
    """The RUL cone: median and 5-95 % band of every prediction against flight index.

    ``truth`` maps flight index -> true RUL [flights] where the test station knows it (with
    ``planned``, the flights to the failure a live injection is steered to); the ``+-alpha``
    cone around it (Saxena's alpha-lambda accuracy zone) is drawn as well.
    """
    truth_name = "planned RUL (test station)" if planned else "true RUL"
    xs = [int(p["flight_index"]) for p in prognoses]

    def q(level: float) -> list[float | None]:
        return [_finite(rul_quantile(p.get("distribution"), level)) for p in prognoses]

    q5, q50, q95 = q(0.05), q(0.5), q(0.95)
    fig = go.Figure()
    band = [(x, lo, hi) for x, lo, hi in zip(xs, q5, q95, strict=True)
            if lo is not None and hi is not None]
    if band:
        bx = [b[0] for b in band]
        fig.add_trace(go.Scatter(x=bx + bx[::-1],
                                 y=[b[2] for b in band] + [b[1] for b in band][::-1],
                                 fill="toself", mode="lines",
                                 fillcolor="rgba(31,119,180,0.18)", line={"width": 0},
                                 name="5-95 % band", hoverinfo="skip"))
    if truth:
        tx = sorted(int(k) for k in truth)
        ty = [float(truth[k]) for k in tx]
        fig.add_trace(go.Scatter(x=tx + tx[::-1],
                                 y=[(1 + alpha) * v for v in ty] + [(1 - alpha) * v
                                                                    for v in ty[::-1]],
                                 fill="toself", fillcolor="rgba(44,160,44,0.15)", mode="lines",
                                 line={"color": "rgba(44,160,44,0.6)", "dash": "dot"},
                                 name=f"{truth_name} ±{100 * alpha:g} %", hoverinfo="skip"))
        fig.add_trace(go.Scatter(x=tx, y=ty, mode="lines", name=truth_name,
                                 line={"color": "#2ca02c", "dash": "dash"}))
    fig.add_trace(go.Scatter(x=xs, y=q50, mode="lines+markers", name="median RUL",
                             marker={"size": 5}, line={"color": "#1f77b4"}))
    return _layout(fig, "RUL cone", "flight index", "RUL [flights]", yaxis_rangemode="tozero")


def rul_histogram(prognosis: Mapping[str, Any] | None, *, failed_at_flight: int | None = None
                  ) -> go.Figure:
    """The latest RUL distribution (probability mass per bin of RUL in flights); for a unit
    that has failed since, titled as the last prediction before the failure."""
    fig = go.Figure()
    if prognosis:
        doc = prognosis.get("distribution") or {}
        edges = [float(e) for e in doc.get("histogram_edges") or []]
        mass = [float(m) for m in doc.get("histogram_mass") or []]
        if len(edges) == len(mass) + 1 and mass:
            centres = [(a + b) / 2 for a, b in zip(edges[:-1], edges[1:], strict=True)]
            widths = [b - a for a, b in zip(edges[:-1], edges[1:], strict=True)]
            fig.add_trace(go.Bar(x=centres, y=mass, width=widths, name="probability mass",
                                 marker={"color": "#1f77b4"}))
        med = _finite(rul_quantile(doc, 0.5))
        if med is not None:
            top = max(mass) if mass else 1.0
            fig.add_trace(go.Scatter(x=[med, med], y=[0, top], mode="lines",
                                     name=f"median {med:.0f}",
                                     line={"color": "#d62728", "dash": "dash"}))
    title, at = "Latest RUL distribution", None
    if prognosis and "flight_index" in prognosis:
        at = int(prognosis["flight_index"])
    detail = None if at is None else f"predicted at flight {at}"
    if failed_at_flight is not None:
        title = f"Failed at flight {failed_at_flight}: no life left"
        detail = None if at is None else f"last prediction, flight {at}"
    return _layout(fig, title, "RUL [flights]", "probability", subtitle=detail,
                   hovermode="closest", bargap=0)


def confusion_matrix(confusion: Mapping[str, Any]) -> go.Figure:
    """Confusion matrix heatmap: colour = row-normalised rate, text = count and rate.

    Rows are the true class, columns the predicted class (``classification.confusion``).
    """
    classes = [str(c) for c in confusion.get("classes", [])]
    counts = confusion.get("counts") or [[0] * len(classes) for _ in classes]
    rates = confusion.get("rates") or [[0.0] * len(classes) for _ in classes]
    text = [[f"{int(n)}<br>{100 * float(r):.0f} %" for n, r in zip(crow, rrow, strict=True)]
            for crow, rrow in zip(counts, rates, strict=True)]
    fig = go.Figure(go.Heatmap(z=rates, x=classes, y=classes, text=text,
                               texttemplate="%{text}", colorscale="Blues", zmin=0, zmax=1,
                               colorbar={"title": {"text": "rate"}},
                               hovertemplate="true %{y}, predicted %{x}: %{text}<extra></extra>"))
    fig.update_yaxes(autorange="reversed")
    acc = confusion.get("accuracy")
    detail = "held-out 30 %"
    if acc is not None:
        detail += f", accuracy {100 * float(acc):.1f} %"
    return _layout(fig, "Confusion matrix", "predicted class", "true class", subtitle=detail,
                   hovermode="closest")
