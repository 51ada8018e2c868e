"""The dashboard pages' wording: what :mod:`server.services.dashboard` reads, in words and
units, and what the pages show that is not in the database (the evaluation document beside the
paper's Table 2; the station page's forms and tables: :mod:`server.web.station_sections`).

Nothing here queries the database or touches the request: the read models come from the
services (``server.services.dashboard``) and these functions take plain data.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from server.services.evaluation_status import read_progress
from server.services.health import SensorFlight
from server.vocabulary import PAPER_TABLE2

__all__ = ["actuator_view", "sensor_view", "finding_text", "condition_name", "evaluation_view"]


def actuator_view(read: dict[str, Any]) -> dict[str, Any]:
    """The actuator page's read model (:func:`server.services.dashboard.actuator_view`) with
    its flights' sensor findings in words."""
    return {**read, "sensor_flights": sensor_view(read["sensor_flights"])}


#: how a sensor's figures are shown: unit and scale per sensor (SI values stored)
_SENSOR_UNITS = {"current": ("A", 1.0), "voltage": ("V", 1.0), "resolver": ("mrad", 1e3),
                 "lvdt": ("µm", 1e6)}
_SENSOR_NAMES = {"current": "phase-current sensor", "voltage": "phase-voltage sensor",
                 "resolver": "resolver (motor angle)", "lvdt": "LVDT (rod position)"}
_METRIC_NAMES = {"noise": "noise floor (rms)", "offset": "offset against the motor shaft",
                 "lsb": "quantisation step", "stuck": "share of the flight stuck",
                 "saturated": "share of the flight at a rail"}


def finding_text(f: dict[str, Any]) -> dict[str, str]:
    """One sensor finding in words and in the sensor's unit."""
    unit, scale = _SENSOR_UNITS.get(f.get("sensor", ""), ("", 1.0))
    if f.get("metric") in ("stuck", "saturated"):
        unit, scale = "%", 100.0

    def num(v: Any) -> str:
        return "–" if v is None else f"{float(v) * scale:.3g}"

    low, high = f.get("low"), f.get("high")
    band = f"≤ {num(high)}" if not low else f"{num(low)} to {num(high)}"
    channel = str(f.get("channel")).replace(".i_sum", ".ia+ib+ic").replace(".v_sum", ".va+vb+vc")
    return {"channel": channel,
            "sensor": _SENSOR_NAMES.get(f.get("sensor", ""), str(f.get("sensor"))),
            "metric": _METRIC_NAMES.get(f.get("metric", ""), str(f.get("metric"))),
            "value": f"{num(f.get('value'))} {unit}", "band": f"{band} {unit}"}


#: a flight condition's words and unit, as the page shows one outside the design
_CONDITION_NAMES = {"temp_ground_c": ("ground temperature", "°C"),
                    "temp_mean_c": ("mean air temperature", "°C"),
                    "load_rms_n": ("aerodynamic load (rms)", "N"),
                    "speed_rms_rad_s": ("motor speed (rms)", "rad/s"),
                    "temp_winding_est_c": ("winding temperature (estimated)", "°C"),
                    "mtel_drag_weight_per_nm": ("hinge-load drag weight", "1/N·m")}


def condition_name(condition: str) -> str:
    """A flight condition in words, e.g. ``temp_mean_c`` -> ``mean air temperature``."""
    return _CONDITION_NAMES.get(condition, (condition, ""))[0]


def outside_text(o: dict[str, Any]) -> dict[str, str]:
    """A condition outside the design, in the columns of a sensor finding."""
    name, unit = _CONDITION_NAMES.get(str(o.get("condition")), (str(o.get("condition")), ""))

    def num(v: Any) -> str:
        return "–" if v is None else f"{float(v):.4g}"

    return {"channel": "conditions", "sensor": "flight conditions",
            "metric": f"{name}: outside the design",
            "value": f"{num(o.get('value'))} {unit}",
            "band": f"{num(o.get('low'))} to {num(o.get('high'))} {unit} (design)"}


def sensor_view(flights: Iterable[SensorFlight]) -> list[dict[str, Any]]:
    """Flights with sensor findings or conditions outside the design (as
    :func:`server.services.dashboard.sensor_flights` orders them), in words."""
    return [{"flight_index": f.flight_index,
             "findings": ([finding_text(x) for x in f.findings]
                          + [outside_text(x) for x in f.outside_design]),
             "set_aside": f.set_aside, "widened": sorted(f.widened)}
            for f in flights]


def evaluation_view(*, data_dir: Path) -> dict[str, Any]:
    """The paper's Table 2 beside ours (``<data_dir>/evaluation/latest.json`` if present)."""
    path = data_dir / "evaluation" / "latest.json"
    ours: dict[str, Any] | None = None
    campaign: str | None = None
    error = None
    if path.exists():
        try:
            doc = json.loads(path.read_text())
            ours = dict(doc.get("prognosis") or {})
            campaign = _campaign_label(doc.get("campaign"), doc.get("created_at"))
        except (OSError, ValueError, AttributeError, TypeError) as exc:
            error = f"{path.name} could not be read: {exc.__class__.__name__}"
    rows = []
    for mode, (ph, ra) in PAPER_TABLE2.items():
        mine = (ours or {}).get(mode) or {}
        saxena, cone = _horizons(mine)
        rows.append({"mode": mode, "paper_ph": ph, "paper_ra": ra,
                     "ph": saxena, "ph_cone": cone, "ra": _percent(mine.get("ra"))})
    running = None if ours is not None else read_progress(data_dir / "evaluation")
    if running is not None:
        since = running.get("since")
        running["minutes"] = (None if not isinstance(since, (int, float))
                              else max(0, round((time.time() - since) / 60)))
        running["count"] = _progress_count(running)
    return {"rows": rows, "has_ours": ours is not None, "error": error,
            "path": "evaluation/latest.json", "campaign": campaign, "running": running}


def _progress_count(status: dict[str, Any]) -> str | None:
    """``12 of 31 patterns`` from a status file's ``done``, ``total`` and ``unit``."""
    done, total, unit = status.get("done"), status.get("total"), status.get("unit")
    if type(done) is not int or type(total) is not int or not 0 <= done <= total or not total:
        return None  # a bool is no count: type(), not isinstance()
    return f"{done} of {total}" + (f" {unit}" if isinstance(unit, str) and unit else "")


def _horizons(mine: dict[str, Any]) -> tuple[float | None, float | None]:
    """(Saxena's PH, the +-20 % cone's PH) of one mode: ``ph`` and ``ph_cone``; a document
    written before the rename has the cone's as ``ph`` and Saxena's as ``ph_band``."""
    if "ph_band" in mine and "ph_cone" not in mine:
        return _num(mine.get("ph_band")), _num(mine.get("ph"))
    return _num(mine.get("ph")), _num(mine.get("ph_cone"))


def _campaign_label(campaign: Any, created_at: Any) -> str | None:
    """``verification campaign, seed 2, quick scale, 1 in 20 flights of a fault run analysed,
    31 patterns; evaluated 2026-12-01T06:38`` from an evaluation document's fields."""
    if not isinstance(campaign, dict):
        return None
    parts = [f"{campaign.get('kind', '?')} campaign"]
    if campaign.get("seed") is not None:
        parts.append(f"seed {campaign['seed']}")
    if campaign.get("scale"):
        parts.append(f"{campaign['scale']} scale")
    every = _num(campaign.get("render_every"))
    if every and every > 1:
        parts.append(f"1 in {int(every)} flights of a fault run analysed")
    if campaign.get("patterns") is not None:
        parts.append(f"{campaign['patterns']} patterns")
    label = ", ".join(parts)
    return f"{label}; evaluated {str(created_at)[:16]}" if created_at else label


def _num(v: Any) -> float | None:
    try:
        f = float(v)
    except (TypeError, ValueError):
        return None
    return f if math.isfinite(f) else None


def _percent(v: Any) -> float | None:
    """RA as a percentage; values in [0, 1] are read as fractions."""
    f = _num(v)
    if f is None:
        return None
    return 100.0 * f if abs(f) <= 1.0 else f
