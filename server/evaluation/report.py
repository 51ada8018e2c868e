"""Figures and reports of an evaluation: plotly figures, the HTML report, Markdown tables.

plotly.js is embedded once in the HTML report (from the installed plotly package, never a CDN);
the per-mode RUL pages reference a local ``plotly.min.js`` written beside them
(``include_plotlyjs="directory"``) or embed it (stand-alone file).
"""

from __future__ import annotations

import html
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import plotly.graph_objects as go
import plotly.io as pio
from plotly.subplots import make_subplots

from server.phm.prognosis.document import rul_point, rul_quantile
from server.vocabulary import PAPER_TABLE2, PROGRESSIVE

from .scoring import ALPHA, pattern_prognosis

__all__ = ["trajectories_figure", "rul_band_figure", "write_html_report", "markdown_tables",
           "write_rul_pages"]

_COLOURS = ("#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#e377c2",
            "#17becf", "#7f7f7f", "#bcbd22")


def trajectories_figure(result: Mapping[str, Any]) -> go.Figure:
    """The paper's Figure 23: RUL median of every pattern against ground truth, per mode.

    Normalised axes: time (t - onset) / life, RUL / life; ground truth 1 - t and the +-20 %
    cone; all rendered flights after detection as lines, the (up to) 10 scored predictions as
    markers.
    """
    modes = [m for m in PROGRESSIVE if m in result["prognosis"]]
    fig = make_subplots(rows=1, cols=max(len(modes), 1), subplot_titles=modes,
                        shared_yaxes=True)
    traces = {t["id"]: t for t in result["patterns"]}
    x = [0.0, 1.0]
    for c, mode in enumerate(modes, start=1):
        fig.add_trace(go.Scatter(x=x, y=[1.0, 0.0], mode="lines", line={"color": "black"},
                                 name="ground truth", showlegend=c == 1), row=1, col=c)
        for sign in (1 + ALPHA, 1 - ALPHA):
            fig.add_trace(go.Scatter(x=x, y=[sign, 0.0], mode="lines",
                                     line={"color": "grey", "dash": "dash"},
                                     name=f"+-{100 * ALPHA:.0f} % cone",
                                     showlegend=c == 1 and sign > 1), row=1, col=c)
        for k, p in enumerate(result["prognosis"][mode]["patterns"]):
            tr = traces[p["id"]]
            onset = tr["onset"] or 0
            life = p["life"]
            det = p["detected_index"]
            colour = _COLOURS[k % len(_COLOURS)]
            if det is None:
                continue
            pts = [(f["index"], _point(f, tr)) for f in tr["flights"]
                   if det <= f["index"] < p["t_eol"]]
            fig.add_trace(go.Scatter(
                x=[(i - onset) / life for i, _ in pts],
                y=[None if v is None else v / life for _, v in pts], mode="lines",
                line={"color": colour, "width": 1}, opacity=0.6, name=p["id"],
                legendgroup=p["id"], showlegend=True), row=1, col=c)
            pr = p["predictions"]
            fig.add_trace(go.Scatter(
                x=[(q["flight"] - onset) / life for q in pr],
                y=[None if q["point"] is None else q["point"] / life for q in pr],
                mode="markers", marker={"color": colour, "size": 6}, legendgroup=p["id"],
                name=f"{p['id']} predictions", showlegend=False), row=1, col=c)
    fig.update_xaxes(title_text="(t - onset) / life [-]", range=[0, 1])
    fig.update_yaxes(title_text="RUL / life [-]", range=[0, 1.6], row=1, col=1)
    fig.update_layout(title="RUL median vs ground truth per fault mode (paper Figure 23)",
                      height=450, width=max(360 * len(modes), 600),
                      legend={"font": {"size": 9}})
    return fig


def _point(flight: Mapping[str, Any], trace: Mapping[str, Any]) -> float | None:
    rul = flight.get("rul")
    if not rul:
        return None
    median = rul_point(rul, "median")
    return float(trace.get("horizon", math.inf)) if median is None else median


_ROW_PX = 320  # height of one pattern's panel in the RUL pages [px]
_GAP_PX = 70  # gap between two panels (room for the x-axis title and the next title) [px]


def rul_band_figure(traces: Sequence[Mapping[str, Any]], mode: str) -> go.Figure:
    """RUL median and 5-95 % band against true RUL over the life, one row per pattern."""
    rows = [t for t in traces if t["mode"] == mode]
    height = _ROW_PX * max(len(rows), 1) + 80
    # a fixed gap in pixels: as a fraction it must stay below 1 / (rows - 1), which a fixed
    # fraction broke at paper scale (25 patterns per mode)
    fig = make_subplots(rows=max(len(rows), 1), cols=1, shared_xaxes=False,
                        subplot_titles=[f"{t['id']} ({t['aircraft']}/{t['position']})"
                                        for t in rows], vertical_spacing=_GAP_PX / height)
    for r, tr in enumerate(rows, start=1):
        fl = tr["flights"]
        idx = [f["index"] for f in fl]
        truth = [f["true_rul"] for f in fl]
        have = [f for f in fl if f["rul"]]
        hx = [f["index"] for f in have]
        q95 = [v if (v := rul_quantile(f["rul"], 0.95)) is not None else tr.get("horizon")
               for f in have]
        q05 = [rul_quantile(f["rul"], 0.05) for f in have]
        med = [_point(f, tr) for f in have]
        first = r == 1
        fig.add_trace(go.Scatter(x=hx, y=q95, mode="lines", line={"width": 0},
                                 showlegend=False, hoverinfo="skip"), row=r, col=1)
        fig.add_trace(go.Scatter(x=hx, y=q05, mode="lines", line={"width": 0},
                                 fill="tonexty", fillcolor="rgba(31,119,180,0.25)",
                                 name="5-95 % band", showlegend=first), row=r, col=1)
        fig.add_trace(go.Scatter(x=hx, y=med, mode="lines+markers", line={"color": "#1f77b4"},
                                 name="RUL median", showlegend=first,
                                 text=[f["fault_mode"] for f in have],
                                 hovertemplate="flight %{x}<br>median %{y:.0f}<br>"
                                 "mode %{text}<extra></extra>"), row=r, col=1)
        fig.add_trace(go.Scatter(x=idx, y=truth, mode="lines", line={"color": "black"},
                                 name="true RUL", showlegend=first), row=r, col=1)
        up = [None if t is None else (1 + ALPHA) * t for t in truth]
        lo = [None if t is None else (1 - ALPHA) * t for t in truth]
        for y, nm in ((up, f"+-{100 * ALPHA:.0f} %"), (lo, None)):
            fig.add_trace(go.Scatter(x=idx, y=y, mode="lines",
                                     line={"color": "grey", "dash": "dash"},
                                     name=nm or "", showlegend=first and nm is not None),
                          row=r, col=1)
        p = pattern_prognosis(tr) if tr["failure"] is not None else None
        if p and p["detected_index"] is not None:
            fig.add_vline(x=p["detected_index"], line={"color": "red", "dash": "dot"},
                          row=r, col=1)
        top = max([v for v in truth if v is not None] or [1.0])
        fig.update_yaxes(title_text="RUL [flights]", range=[0, 1.8 * top], row=r, col=1)
        fig.update_xaxes(title_text="flight since onset", row=r, col=1)
    fig.update_layout(title=f"{mode}: RUL median and 5-95 % band vs true RUL "
                      "(red dotted: detection)", height=height, width=900)
    return fig


def write_rul_pages(result: Mapping[str, Any], out_dir: Path, *,
                    include_plotlyjs: bool | str = "directory") -> list[Path]:
    """One HTML page per progressive mode (``rul_<MODE>.html``)."""
    paths = []
    for mode in PROGRESSIVE:
        if not any(t["mode"] == mode for t in result["patterns"]):
            continue
        path = out_dir / f"rul_{mode}.html"
        rul_band_figure(result["patterns"], mode).write_html(
            path, include_plotlyjs=include_plotlyjs, full_html=True)
        paths.append(path)
    return paths


def _f(v: Any, spec: str = ".2f") -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "-"
    return format(v, spec)


def _ci(v: Any, ci: Any, spec: str = ".2f", scale: float = 1.0) -> str:
    """``mean [lo, hi]`` (times ``scale``), ``-`` without a mean, the mean alone without an
    interval."""
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "-"
    text = _f(scale * v, spec)
    if not ci or any(c is None for c in ci):
        return text
    return f"{text} [{_f(scale * ci[0], spec)}, {_f(scale * ci[1], spec)}]"


def _get_ci(r: Mapping[str, Any], key: str, spec: str = ".2f", scale: float = 1.0) -> str:
    return _ci(r.get(key), r.get(f"{key}_ci"), spec, scale)


def _rate_text(r: Mapping[str, Any]) -> str:
    if r.get("rate") is None:
        return f"{r['events']} on 0 unit-flights"
    lo, hi = r["interval"]
    return (f"{r['events']} on {r['unit_flights']} unit-flights, {r['rate']:.1e} "
            f"[{lo:.1e}, {hi:.1e}]")


def _beside_design(pu: Mapping[str, Any]) -> list[str]:
    """The design's measured rate over its own long healthy lives, and whether this rate
    falls inside its interval (no lines when the model carried none)."""
    measured = pu.get("design_measured")
    if not measured:
        return []
    inside = pu.get("within_design_interval")
    verdict = ("" if inside is None else
               f": this rate is {'inside' if inside else 'outside'} its interval")
    return [f"The design's own long healthy lives (leave-one-aircraft-out): "
            f"{_rate_text(measured)}{verdict}.", ""]


def _per_unit_flight(det: Mapping[str, Any]) -> list[str]:
    """The false alarms per unit-flight of every unit without a fault, with their interval
    beside the detector's design rate, by cause and reference age."""
    pu = det.get("per_unit_flight")
    if not pu:
        return []
    design = pu.get("design_rate")
    beside = ("" if design is None else
              f"; design rate {design:.1e}, "
              f"{'inside' if pu.get('design_rate_inside') else 'outside'} the interval")
    lines = ["", f"False alarms per unit-flight, every actuator without a fault: "
                 f"{_rate_text(pu)} ({pu['level']:.0%} exact interval){beside}.", "",
             *_beside_design(pu),
             "| cause | alarm events | unit-flights | rate [90 % interval] |", "|---|---|---|---|"]
    for cause, r in pu["by_cause"].items():
        rate = "-" if r["rate"] is None else (f"{r['rate']:.1e} [{r['interval'][0]:.1e}, "
                                              f"{r['interval'][1]:.1e}]")
        lines.append(f"| {cause} | {r['events']} | {r['unit_flights']} | {rate} |")
    ages = ", ".join(f"{k}: {v}" for k, v in pu["events_by_reference_age"].items())
    lines += ["", f"Alarm events by age of the unit's reference [flights since installation]: "
                  f"{ages or 'none'}."]
    if "events_by_feature" in pu:  # evaluations before it was kept have no features
        feats = ", ".join(f"{k}: {v}" for k, v in pu["events_by_feature"].items())
        lines.append(f"Alarm events by the feature they were raised on: {feats or 'none'}.")
    return lines


def _isolation(det: Mapping[str, Any]) -> list[str]:
    """How often an alarm after onset named the faulty unit (ambiguity groups included)."""
    iso = det.get("isolation")
    if not iso or not iso["named_right"]["alarms"]:
        return []

    def share(r: Mapping[str, Any]) -> str:
        lo, hi = r["interval"]
        return f"{r['hits']} of {r['alarms']}, {r['share']:.1%} [{lo:.1%}, {hi:.1%}]"

    groups = iso["ambiguity_groups"]
    text = (f"Isolation, every alarm after onset (partner and other surface included): named "
            f"the faulty unit {share(iso['named_right'])}; the faulty unit in its group "
            f"{share(iso['faulty_in_group'])}; {groups} ambiguity groups")
    if groups:
        text += (f", named right {iso['groups_named_right']} times, mean probability of the "
                 f"named unit {iso['groups_mean_named_probability']:.2f}")
    return ["", text + "."]


def _confirmation_line(cls: Mapping[str, Any]) -> str:
    """The rule and the flights from the first alarm to confirmation."""
    rule, d = cls["confirmation_rule"], cls["flights_to_confirmation"]
    said = (f"Confirmed when the leading class led {rule['flights']} classified flights in a "
            f"row at a probability of {rule['probability']:.2f} or more: {d['confirmed']} "
            f"detected faults confirmed, {d['unconfirmed']} never"
            + (f" ({d['ended_before_due']} of them: the pattern ended first)"
               if d.get("ended_before_due") else ""))
    if d["mean"] is None:
        return said + "."
    return (said + f"; flights from the first alarm to confirmation mean {d['mean']:.1f}, "
            f"90th percentile {d['p90']:.0f}, max {d['max']:.0f}.")


def markdown_tables(result: Mapping[str, Any]) -> dict[str, str]:
    """Markdown tables: detection, confusion (first alarm, last flight), prognosis (median
    and most probable RUL), timing. Means as "mean [lo, hi]", the 90 % bootstrap interval
    over patterns."""
    det = result["detection"]
    fa = det["false_alarms"]
    rate = fa.get("rate_per_flight")
    lines = [f"False alarms: {fa['healthy_patterns_with_alarm']} of {fa['healthy_patterns']} "
             f"healthy cycles with an alarm; {fa['false_alarm_events']} alarm events on "
             f"{fa['healthy_flights']} healthy flights (incl. pre-onset flights of fault "
             f"patterns), rate per healthy flight "
             f"{_ci(rate, fa.get('rate_per_flight_ci'), '.4f')} "
             "(paper: 0 on 25 healthy cycles).", *_per_unit_flight(det), *_isolation(det), "",
             "| mode | patterns | detected | detection rate | detection time mean [% life] | "
             "max [% life] | flights after onset mean | max | alarms on other actuators |",
             "|---|---|---|---|---|---|---|---|---|"]
    for m, r in det["per_mode"].items():
        lines.append(f"| {m} | {r['patterns']} | {r['detected']} | {_get_ci(r, 'rate')} | "
                     f"{_get_ci(r, 'pct_life_mean', '.1f')} | {_f(r['pct_life_max'], '.1f')} | "
                     f"{_get_ci(r, 'flights_after_onset_mean', '.1f')} | "
                     f"{_f(r['flights_after_onset_max'], '.0f')} | {r['other_unit_alarms']} |")
    sens = result.get("sensors")
    if sens:
        named = ", ".join(f"{k} ({n})" for k, n in sens["by_channel"].items()) or "none"
        lines += ["", f"Sensor findings: {sens['flights_with_finding']} of {sens['flights']} "
                      f"flights ({sens['healthy_cycle_flights_with_finding']} of "
                      f"{sens['healthy_cycle_flights']} flights of healthy cycles); by channel "
                      f"and figure, flights: {named}."]
    out = {"detection": "\n".join(lines)}
    for key, title in (("at_first_alarm", "at the first alarm"),
                       ("at_confirmation", "at confirmation"),
                       ("at_last_flight", "at the last flight")):
        if key not in result["classification"]:  # evaluations before it was kept
            continue
        c = result["classification"][key]
        cols = c["columns"]
        t = [f"Classification {title} (rows: true mode, columns: predicted; accuracy "
             f"{_ci(c['accuracy'], c.get('accuracy_ci'), '.1f', 100.0)} %)", "",
             "| true \\ predicted | " + " | ".join(cols) + " | recall [%] |",
             "|---|" + "---|" * (len(cols) + 1)]
        for row, vals in zip(c["rows"], c["matrix"], strict=True):
            pc = c["per_class"][row]
            t.append(f"| {row} | " + " | ".join(str(v) for v in vals) +
                     f" | {_ci(pc['recall'], pc.get('recall_ci'), '.0f', 100.0)} |")
        if key == "at_confirmation":
            t += ["", _confirmation_line(result["classification"])]
        cal = (result["classification"].get("probability_calibration") or {}).get(key)
        if cal and cal["n"]:
            t += ["", f"Shown probability of the leading class: mean "
                      f"{100 * cal['mean_confidence']:.1f} % against {100 * cal['accuracy']:.1f} "
                      f"% right; log-loss of the true class {cal['log_loss']:.2f}; "
                      f"{cal['at_least_99pct']} of {cal['n']} at 99 % or more."]
        out[key] = "\n".join(t)
    p = ["Prognosis, RUL median as point estimate; mean [90 % bootstrap interval over "
         "patterns]. PH: Saxena's (every later estimate within true RUL +- 0.2 x life), PH "
         "cone: within +-20 % of the true RUL; both over the life. Calibration: share of the "
         "predictions whose central 50 / 90 % RUL interval holds the true RUL; width: the "
         "interval's mean width [flights] where it closes within the horizon.", "",
         "| mode | PH (Saxena) [-] | PH cone (+-20 %) [-] | PH [-] paper | RA [%] | RA [%] paper | "
         "PH from detection [-] | alpha-lambda (0.2, 0.5) | CRA [%] | convergence [-] | "
         "calibration 50 % | calibration 90 % | width 90 % [flights] | predictions | "
         "patterns (with predictions) |",
         "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for m, r in result["prognosis"].items():
        cal = r.get("calibration") or {}
        p.append(f"| {m} | {_get_ci(r, 'ph')} | {_get_ci(r, 'ph_cone')} | "
                 f"{PAPER_TABLE2[m][0]:.2f} | {_get_ci(r, 'ra', '.1f')} | "
                 f"{PAPER_TABLE2[m][1]:.1f} | {_get_ci(r, 'ph_from_detection')} | "
                 f"{_get_ci(r, 'alpha_lambda')} | {_get_ci(r, 'cra', '.1f', 100.0)} | "
                 f"{_get_ci(r, 'convergence')} | {_get_ci(cal, 'central_50')} | "
                 f"{_get_ci(cal, 'central_90')} | {_get_ci(cal, 'width_90_flights', '.0f')} | "
                 f"{cal.get('n_predictions', '-')} | "
                 f"{r['n_patterns']} ({r['n_with_predictions']}) |")
    out["prognosis"] = "\n".join(p)
    mp = ["Prognosis, most probable RUL as point estimate; mean [90 % bootstrap interval].",
          "", "| mode | PH (Saxena) [-] | PH cone (+-20 %) [-] | RA [%] |", "|---|---|---|---|"]
    for m, r in result["prognosis"].items():
        q = r.get("most_probable") or {}
        mp.append(f"| {m} | {_get_ci(q, 'ph')} | {_get_ci(q, 'ph_cone')} | "
                  f"{_get_ci(q, 'ra', '.1f')} |")
    out["prognosis_most_probable"] = "\n".join(mp)
    tm = result["timing"]
    rows = [
        ("features + detection per 80 Hz step, 3 EMAs, 20 features (amortised over a flight)",
         tm.get("features_detection_per_step_ms"), "11.3"),
        ("  of which feature extraction per step", tm.get("features_per_step_ms"), ""),
        ("  of which z-scores + detection per step", tm.get("detection_per_step_ms"), ""),
        ("Parquet read per step (not in the paper's figure)", tm.get("read_per_step_ms"), ""),
        ("feature extraction per flight", (tm.get("features") or {}).get(
            "features_per_flight_ms"), ""),
        ("z-scores + detection per flight (3 actuators)", tm.get("detection_per_flight_ms"), ""),
        ("particle-filter update (200 particles, incl. RLS)", tm.get("pf_update_ms"), ""),
        ("  RLS step", tm.get("rls_ms"), ""),
        ("long-term prediction (RUL distribution)", tm.get("pf_predict_ms"), ""),
        ("update + prediction cycle", tm.get("pf_cycle_ms"), "7.4"),
        ("RLS share of the cycle [%]", tm.get("rls_share_pct"), "2.25"),
        ("whole chain per flight (3 actuators, from cached features)",
         tm.get("chain_per_flight_ms"), ""),
    ]
    t = ["| what (mean per call) | ours [ms] | paper [ms] |", "|---|---|---|"]
    for name, v, paper in rows:
        t.append(f"| {name} | {_f(v, '.2e' if v is not None and v < 0.01 else '.3f')} | "
                 f"{paper} |")
    out["timing"] = "\n".join(t)
    return out


def _md_to_html_table(md: str) -> str:
    """Tiny Markdown-table-to-HTML conversion (the tables written by :func:`markdown_tables`)."""
    parts: list[str] = []
    table: list[list[str]] = []

    def flush() -> None:
        if not table:
            return
        head, *body = table
        parts.append("<table><thead><tr>" + "".join(f"<th>{html.escape(c)}</th>" for c in head)
                     + "</tr></thead><tbody>" + "".join(
                         "<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in r) + "</tr>"
                         for r in body) + "</tbody></table>")
        table.clear()

    for line in md.splitlines():
        if line.startswith("|"):
            cells = [c.strip() for c in line.strip().strip("|").split("|")]
            if all(set(c) <= {"-"} for c in cells):
                continue
            table.append(cells)
        else:
            flush()
            if line.strip():
                parts.append(f"<p>{html.escape(line)}</p>")
    flush()
    return "\n".join(parts)


def write_html_report(result: Mapping[str, Any], path: Path, *,
                      extra_figures: Sequence[go.Figure] = ()) -> Path:
    """The evaluation as one HTML page; plotly.js embedded once (first figure)."""
    tables = markdown_tables(result)
    camp = result["campaign"]
    figs = [trajectories_figure(result), *extra_figures]
    divs = [pio.to_html(f, include_plotlyjs=(i == 0), full_html=False)
            for i, f in enumerate(figs)]
    model = result.get("model", {})
    body = [
        "<h1>PHM chain evaluation</h1>",
        f"<p>Campaign <code>{html.escape(str(camp['dir']))}</code> ({camp['kind']}, seed "
        f"{camp['seed']}, scale {camp['scale']}, {camp['patterns']} patterns, "
        f"{camp['flights']} rendered flights, render every {camp['render_every']}). Model: "
        f"{html.escape(str(model.get('source', '-')))}.</p>",
        "<h2>Detection</h2>", _md_to_html_table(tables["detection"]),
        "<h2>Classification</h2>", _md_to_html_table(tables["at_first_alarm"]),
        *([_md_to_html_table(tables["at_confirmation"])] if "at_confirmation" in tables
          else []),
        _md_to_html_table(tables["at_last_flight"]),
        "<h2>Prognosis (paper Table 2)</h2>", _md_to_html_table(tables["prognosis"]),
        _md_to_html_table(tables["prognosis_most_probable"]),
        divs[0],
        "<h2>Timing (paper section 5.1)</h2>", _md_to_html_table(tables["timing"]),
        *divs[1:],
    ]
    page = ("<!DOCTYPE html><html><head><meta charset='utf-8'><title>PHM evaluation</title>"
            "<style>body{font-family:sans-serif;margin:1.5em;max-width:1500px}"
            "table{border-collapse:collapse;margin:.5em 0}td,th{border:1px solid #ccc;"
            "padding:2px 6px;text-align:right}th{background:#f3f3f3}</style></head><body>"
            + "\n".join(body) + "</body></html>")
    path.write_text(page, encoding="utf-8")
    return path
