"""The dashboard pages' read models: what each page shows, gathered from the other services.

One job: read. Each function takes ``*, session`` and returns plain dicts and the services'
rows for the templates and :mod:`server.web.figures`; wording and units are the web layer's
(:mod:`server.web.data`). Query counts are fixed per page (the fleet page: the two queries of
:func:`server.services.health.fleet_grid` and one for the flights whose analysis failed).
"""

from __future__ import annotations

import sys
from typing import Any

from sqlalchemy.orm import Session

from server.services import analysis as analysis_service
from server.services import fleet as fleet_service
from server.services import flights as flight_service
from server.services import health as health_service
from server.services import maintenance as maintenance_service
from server.services import models as model_service
from server.services import station
from server.services import urgency as urgency_rule
from server.vocabulary import (
    OWN_FEATURE,
    POSITIONS,
    SENSOR_OF_SIGNAL,
    STATION_LIVE,
)

__all__ = ["STATUS_RANK", "CONDITION_MOVES", "fleet_view", "failed_flights", "alarms_view",
           "urgency_rule_view", "sensor_flights", "station_marks", "actuator_view",
           "models_view", "station_view", "health_dict", "prognosis_dict"]

#: the grid's colours, most urgent first (the urgency rule's buckets, server.services.urgency)
STATUS_RANK = {urgency_rule.COLOUR[b]: i for i, b in enumerate(urgency_rule.BUCKETS)}


def fleet_view(*, session: Session, sort: str = "rul", base: str | None = None,
               status: str | None = None) -> dict[str, Any]:
    """Aircraft rows x positions, sorted by urgency (the most urgent cell, then the shortest
    median RUL) or tail; filtered."""
    cells = health_service.fleet_grid(session=session)
    bases = sorted({c.base for c in cells})
    by_tail: dict[str, dict[str, Any]] = {}
    for c in cells:
        row = by_tail.setdefault(c.tail, {"tail": c.tail, "base": c.base, "cells": {}})
        row["cells"][c.position] = c
    counts = {s: sum(1 for c in cells if c.status == s) for s in STATUS_RANK}
    rows = list(by_tail.values())
    for row in rows:
        present = list(row["cells"].values())
        row["worst"] = min((c.status for c in present), key=STATUS_RANK.__getitem__,
                           default="green")
        ruls = [c.rul_median for c in present if c.rul_median is not None]
        row["min_rul"] = min(ruls) if ruls else None
    if base:
        rows = [r for r in rows if r["base"] == base]
    if status in STATUS_RANK:
        rows = [r for r in rows if any(c.status == status for c in r["cells"].values())]
    if sort == "tail":
        rows.sort(key=lambda r: r["tail"])
    else:
        rows.sort(key=lambda r: (STATUS_RANK[r["worst"]], r["min_rul"] is None,
                                 r["min_rul"] or 0.0, r["tail"]))
    return {"rows": rows, "positions": POSITIONS, "bases": bases, "counts": counts,
            "sort": "tail" if sort == "tail" else "rul", "base": base or "",
            "status": status if status in STATUS_RANK else "", "n_actuators": len(cells),
            "failed_flights": failed_flights(session=session)}


def failed_flights(*, session: Session, limit: int = 20) -> list[dict[str, Any]]:
    """Flights whose analysis was given up, newest first, with why (an admin retries them)."""
    return [{"id": f.id, "tail": f.tail, "flight": f.flight_code, "updated_at": f.updated_at,
             "reason": _failure_reason(f.reasons)}
            for f in analysis_service.failed_flights(session=session, limit=limit)]


def _failure_reason(reasons: list[dict[str, Any]]) -> str:
    first = reasons[0] if reasons else {}
    error = (first.get("details") or {}).get("error")
    return str(error or first.get("message") or "unknown")


def alarms_view(*, session: Session, status: str | None, limit: int = 200) -> dict[str, Any]:
    """The inbox's rows (a winglet pair's two alarms are one row) and how many there are:
    the count is of rows, as shown."""
    # every alarm (the service orders them all in memory anyway), paired, then cut
    rows, _ = health_service.list_alarms(session=session, status=status, tail=None,
                                         limit=sys.maxsize, offset=0)
    paired = health_service.pair_winglet_alarms(rows)
    items = [{**_alarm_item(r), "partner": None if p is None else _alarm_item(p),
              "failed_drive": _failed_drive(r, p)} for r, p in paired[:limit]]
    return {"items": items, "total": len(paired), "status": status or "",
            "shown": len(items), "n_pairs": sum(1 for _, p in paired if p is not None),
            "rule": urgency_rule_view()}


def _alarm_item(r: Any) -> dict[str, Any]:
    return {"alarm": r.alarm, "actuator": r.actuator, "tail": r.tail, "urgency": r.urgency,
            "deferral_expired": r.deferral_expired, "rul_median": r.rul_median}


def _failed_drive(row: Any, partner: Any) -> Any:
    """The failed unit of an inbox row, if any; on a winglet-pair row, the failure record
    names the drive the pair's evidence could not."""
    return next((x.actuator for x in (row, partner)
                 if x is not None and x.actuator.failed_at_flight is not None), None)


def urgency_rule_view() -> dict[str, Any]:
    """The rule's constants, for the hint on the pages."""
    return {"quantile": urgency_rule.RUL_LOW_QUANTILE,
            "act_within_max": urgency_rule.ACT_WITHIN_MAX_FLIGHTS}


def health_dict(row: Any) -> dict[str, Any]:
    return {"flight_index": row.flight_index, "flight_id": row.flight_id,
            "features": row.features, "scores": row.scores,
            "confidence": row.confidence, "alarm": row.alarm,
            "class_probabilities": row.class_probabilities}


def prognosis_dict(row: Any) -> dict[str, Any]:
    return {"flight_index": row.flight_index, "flight_id": row.flight_id,
            "fault_mode": row.fault_mode, "distribution": row.distribution}


def sensor_flights(*, session: Session, actuator_id: int, limit: int
                   ) -> list[health_service.SensorFlight]:
    """The latest flights (at most ten) with sensor findings of an actuator, newest first;
    :func:`server.web.data.sensor_view` puts them in words."""
    flights = health_service.sensor_findings(session=session, actuator_id=actuator_id,
                                             limit=limit)
    return list(reversed(flights[-10:]))


#: what each test-station condition moves among the chain's inputs (sim_worker/conditions.py
#: for the physics, docs/FEATURES.md for the features), shown beside the feature trends
CONDITION_MOVES = {
    "ambient_offset": "T_amb and the winding temperature (R̂): the baselines' temperature "
                      "covariates; F_MTEL's cruise window (T_amb ≤ −37 °C: above +3 K it "
                      "finds no cruise and gives no value)",
    "load_scale": "hinge load, hence phase current: F_MTEL's load |L|, F_MTWEAR's flank "
                  "pressing, F_DMD's and F_SE's q-axis terms",
    "load_offset": "hinge load, hence phase current: F_MTEL's load |L|, F_MTWEAR's flank "
                   "pressing, F_DMD's and F_SE's q-axis terms",
    "command_scale": "commanded motion: speed and travel, the moving windows of every feature",
    "base": "ground temperature: the baselines' temperature covariates",
}


def _under_by_code(session: Session, actuator: Any) -> dict[str, list[tuple[str, str]]]:
    """Flight code -> (what was live, what it moves) of the test station on this actuator's
    flights: fault and sensor injections at its position, conditions on its aircraft."""
    tail, position = actuator.aircraft.tail, actuator.position
    out: dict[str, list[tuple[str, str]]] = {}
    faults, _ = station.list_(session=session, kind=station.FAULTS, tail=tail, status=None,
                              limit=100, offset=0)
    for inj, _t in reversed(faults):
        if inj.position == position:
            for gt in station.list_truth(session=session, kind=station.FAULTS,
                                         item_id=inj.id):
                out.setdefault(gt.flight_code, []).append(
                    (f"fault {inj.fault_mode}", f"{position}.{OWN_FEATURE[inj.fault_mode]}"))
    sensors, _ = station.list_(session=session, kind=station.SENSORS, tail=tail, status=None,
                               limit=100, offset=0)
    for sensed, _t in reversed(sensors):
        if sensed.position == position:
            channels = ", ".join(f"{position}.{s}" for s, of in SENSOR_OF_SIGNAL.items()
                                 if of == sensed.sensor)
            for st in station.list_truth(session=session, kind=station.SENSORS,
                                         item_id=sensed.id):
                out.setdefault(st.flight_code, []).append(
                    (f"{sensed.sensor} {sensed.kind} {sensed.value:g}", channels))
    for code, rows in station.flights_under(session=session, kind=station.CONDITIONS,
                                            aircraft_id=actuator.aircraft_id).items():
        out.setdefault(code, []).extend(
            (station.describe_condition(c), CONDITION_MOVES[c.kind]) for c, _truth in rows)
    return out


def station_marks(*, session: Session, actuator: Any, records: list[dict[str, Any]]
                  ) -> list[dict[str, Any]]:
    """Runs of consecutive analysed flights flown under the same test-station injections or
    conditions: first and last flight index, what was live and what each moves."""
    under = _under_by_code(session, actuator)
    if not under:
        return []
    codes = flight_service.flight_codes(session=session,
                                        flight_ids=[r["flight_id"] for r in records])
    marks: list[dict[str, Any]] = []
    previous: tuple[tuple[str, str], ...] = ()
    for r in records:
        live = tuple(under.get(codes.get(r["flight_id"]) or "", ()))
        if live and live == previous:
            marks[-1]["last"] = r["flight_index"]
        elif live:
            marks.append({"first": r["flight_index"], "last": r["flight_index"],
                          "live": [{"what": w, "moves": m} for w, m in live]})
        previous = live
    return marks


def actuator_view(*, session: Session, actuator_id: int, limit: int = 500) -> dict[str, Any]:
    """The actuator page: its health records, prognoses and the truth the test station knows
    for them, alarms and their events, urgency, maintenance trail, detector levels, the
    flights with sensor findings (``sensor_flights``: the service's rows, not yet in words)
    and the runs of flights flown under the test station."""
    actuator = fleet_service.get_actuator(session=session, actuator_id=actuator_id)
    tail = actuator.aircraft.tail
    records = [health_dict(r) for r in health_service.health_records(
        session=session, actuator_id=actuator_id, limit=limit)]
    # the prognoses of the unit's current alarm only: none after a no-fault-found
    progs = [prognosis_dict(p) for p in health_service.current_prognoses(
        session=session, actuator_id=actuator_id, limit=limit)]
    history, _ = fleet_service.list_actuators(session=session, tail=tail,
                                              position=actuator.position, installed=None,
                                              limit=100, offset=0)
    previous = [a for a in history if a.id != actuator.id]
    alarms, _ = health_service.list_alarms(session=session, status=None, tail=tail, limit=500,
                                           offset=0)
    own_alarms = [r for r in alarms if r.actuator.id == actuator.id]
    state_urgency, open_alarm, deferral_expired = health_service.actuator_urgency(
        session=session, actuator=actuator)
    pair = None if open_alarm is None or actuator.removed_at is not None else \
        health_service.winglet_partner_alarm(session=session, alarm_id=open_alarm.id)
    pair_alarm = None if pair is None else {
        "alarm_id": pair[0].id, "fault_mode": pair[0].fault_mode,
        "actuator_id": pair[1].id, "position": pair[1].position,
        "failed_drive": next((a for a in (actuator, pair[1])
                              if a.failed_at_flight is not None), None)}
    events = health_service.alarm_events(session=session,
                                         alarm_ids=[r.alarm.id for r in own_alarms])
    trail = maintenance_service.position_trail(
        session=session, actuator_ids=[a.id for a in history])

    # Ground truth from the test station: injections at this aircraft/position, aligned to the
    # prognoses through the flight codes of the flights those prognoses were made on.
    injections, _ = station.list_(session=session, kind=station.FAULTS, tail=tail,
                                  status=None, limit=100, offset=0)
    # While a steered injection is live its true RUL is the test station's plan (the flights
    # to its planned failure); at failure the sim worker back-fills the true one. Concurrent
    # faults on the unit: it fails at the first of them, so a flight's truth is the least.
    truth_by_code: dict[str, float] = {}
    planned = False
    for inj, _t in injections:
        if inj.position != actuator.position:
            continue
        live_plan = inj.planned_failure_flight if inj.status in STATION_LIVE else None
        for gt in station.list_truth(session=session, kind=station.FAULTS, item_id=inj.id):
            if gt.true_rul_flights is not None:
                rul = float(gt.true_rul_flights)
            elif live_plan is not None:
                rul = float(max(live_plan - gt.flight_number, 0))
                planned = True
            else:
                continue
            truth_by_code[gt.flight_code] = min(rul, truth_by_code.get(gt.flight_code, rul))
    truth: dict[int, float] = {}
    if truth_by_code and progs:
        codes = flight_service.flight_codes(session=session,
                                            flight_ids=[p["flight_id"] for p in progs])
        for p in progs:
            code = codes.get(p["flight_id"])
            if code in truth_by_code:
                truth[p["flight_index"]] = truth_by_code[code]

    z_names = sorted({n for r in records for n in (r["scores"] or {}).get("z", {})})
    model_id = next((r.model_version_id for r in reversed(
        health_service.health_records(session=session, actuator_id=actuator_id, limit=1))),
        None)
    if model_id is None:
        active = model_service.active_version(session=session)
        model_id = None if active is None else active.id
    levels = model_service.detector_levels(session=session, version_id=model_id,
                                           features=z_names)
    latest = records[-1] if records else None
    return {"actuator": actuator, "tail": tail, "records": records, "prognoses": progs,
            "truth": truth, "truth_planned": planned, "previous": previous,
            "alarms": own_alarms, "alarm_events": events,
            "alarms_by_id": {r.alarm.id: r.alarm for r in alarms}, "band": levels.band,
            "threshold": levels.threshold, "alarm_confidence": levels.alarm_confidence,
            "latest": latest, "latest_prognosis":
            progs[-1] if progs else None, "urgency": state_urgency, "open_alarm": open_alarm,
            "deferral_expired": deferral_expired, "trail": trail, "pair_alarm": pair_alarm,
            "rule": urgency_rule_view(),
            "sensor_flights": sensor_flights(session=session, actuator_id=actuator_id,
                                             limit=limit),
            "station_marks": station_marks(session=session, actuator=actuator,
                                           records=records)}


def models_view(*, session: Session, model_id: int | None) -> dict[str, Any]:
    """The model versions, the one chosen (asked for, else the active one, else the first
    with a confusion matrix) and its confusion matrix's per-class figures."""
    versions = model_service.list_versions(session=session)
    chosen = None
    if model_id is not None:
        chosen = next((v for v in versions if v.id == model_id), None)
    if chosen is None:
        chosen = next((v for v in versions if v.active), None) or next(
            (v for v in versions if (v.metrics or {}).get("confusion")), None)
    confusion = (chosen.metrics or {}).get("confusion") if chosen else None
    per_class = []
    if confusion:
        for i, c in enumerate(confusion.get("classes", [])):
            per_class.append({
                "cls": c, "support": _at(confusion.get("support"), i),
                "recall": _at(confusion.get("recall"), i),
                "precision": _at(confusion.get("precision"), i)})
    return {"versions": versions, "chosen": chosen, "confusion": confusion,
            "per_class": per_class}


def _at(values: Any, i: int) -> Any:
    return values[i] if isinstance(values, list) and i < len(values) else None


def station_view(*, session: Session, limit: int = 50) -> dict[str, Any]:
    """The aircraft the station's forms offer (``tails``) and, per kind of the registry (its
    key), its latest items (``station_items``), each with its last ground truth."""
    aircraft, _ = fleet_service.list_aircraft(session=session, base=None, limit=1000, offset=0)
    return {"tails": [a.tail for a in aircraft],
            "station_items": {kind.key: _latest_with_truth(session, kind, limit)
                              for kind in station.KINDS}}


def _latest_with_truth(session: Session, kind: station.Kind, limit: int
                       ) -> list[dict[str, Any]]:
    """The latest items of ``kind`` (``item``), each with its tail, whether it is live, its
    truth's count and last entry, and what an operator should know of it while it is live
    (the kind's ``warnings``, e.g. a fault's span outside the active model's training)."""
    rows, _ = station.list_(session=session, kind=kind, tail=None, status=None, limit=limit,
                            offset=0)
    items = []
    for row, tail in rows:
        truth = station.list_truth(session=session, kind=kind, item_id=row.id)
        live = row.status in STATION_LIVE
        items.append({"item": row, "tail": tail, "truth_count": len(truth),
                      "truth_latest": truth[-1] if truth else None, "live": live,
                      "warnings": kind.warnings(session, row) if live and kind.warnings
                      else []})
    return items
