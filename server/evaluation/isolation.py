"""Isolation: whether each alarm names the unit that carries the fault.

Every alarm raised after a fault's onset in a fault pattern is an isolation case: the faulty
unit's own alarm, a partner drive's and one on the other surface alike. The alarm names the
units it may belong to with a probability each (``DetectionResult.isolation``: its own unit
alone, or both winglet drives, an ambiguity group); the named unit is the most probable one.
Reported: the share of alarms whose named unit is faulty, and whose group holds a faulty unit,
each with its exact 90 % interval; and for the ambiguity groups, the mean probability they gave
the unit they named beside how often it was right (a calibration check).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from server.phm.metrics import proportion_interval
from server.vocabulary import alarming_positions

from .false_alarms import LEVEL

__all__ = ["isolation_cases", "summarise_isolation"]


def _share(hits: int, n: int) -> dict[str, Any]:
    if n == 0:
        return {"hits": 0, "alarms": 0, "share": None, "interval": None}
    return {"hits": hits, "alarms": n, "share": hits / n,
            "interval": proportion_interval(hits, n, LEVEL)}


def isolation_cases(trace: Mapping[str, Any]) -> list[dict[str, Any]]:
    """The pattern's alarms after onset, each with the units it named and whether it was
    right. Healthy patterns have none (their alarms are false alarms, not isolation)."""
    if trace["mode"] == "healthy":
        return []
    onset = int(trace["onset"] or 0)
    faulty = alarming_positions(trace["mode"], trace["position"],
                                pair_rod_ends=bool(trace.get("pair_rod_ends", False)))
    cases = []
    for f in trace["flights"]:
        if int(f["index"]) < onset:
            continue
        for unit in f["new_alarms"]:
            group = (f.get("isolation") or {}).get(unit) or {unit: 1.0}
            named = max(group, key=lambda u: group[u])
            cases.append({"pattern": trace["id"], "flight": int(f["index"]), "unit": unit,
                          "group": dict(group), "named": named, "right": named in faulty,
                          "in_group": bool(faulty & set(group))})
    return cases


def summarise_isolation(traces: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """Isolation accuracy over every alarm after onset, ambiguity groups apart."""
    cases = [c for t in traces for c in isolation_cases(t)]
    groups = [c for c in cases if len(c["group"]) > 1]
    return {"level": LEVEL,
            "named_right": _share(sum(c["right"] for c in cases), len(cases)),
            "faulty_in_group": _share(sum(c["in_group"] for c in cases), len(cases)),
            "ambiguity_groups": len(groups),
            "groups_named_right": sum(c["right"] for c in groups),
            "groups_mean_named_probability": (
                sum(max(c["group"].values()) for c in groups) / len(groups) if groups
                else None),
            "wrong": [c for c in cases if not c["right"]]}
