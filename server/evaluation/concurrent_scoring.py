"""Scoring a concurrent campaign's traces (:mod:`.concurrent`): each fault's detection and
naming, both modes named by the first fault's half life, the RUL of the earlier failure.

Per pattern, from its truth (each fault's unit, onset, and end: its failure, or the flight its
unit failed of the other fault, censoring it):

- a fault is *alarmed* when its unit is in alarm on a flight from its onset to its end,
  *named* from the first such flight whose modes present hold its mode, and *confirmed* on the
  first flight up to its end that confirmed its mode on its unit (as the alarm's class, or
  present beside it: :mod:`server.phm.classification.confirmation`);
- the *half flight* is the first fault's onset plus half its life (to its failure; a censored
  first fault's planned span); the pattern is *named by half* when every fault was named on a
  flight at or before it, and *named at half* when, on the last flight at or before it, every
  fault's unit still names that fault's mode (the set is provisional: a mode may drop out and
  come back); patterns whose second fault starts after the half flight can be neither, and
  are counted apart;
- the *earlier failure* is the first fault to fail; its unit's RUL (the leading mode's
  prognosis) is scored against it as a single fault's is (:func:`.scoring.pattern_prognosis`:
  Saxena's horizon, the cone's, RA);
- a mode named on a unit that does not carry it on that flight is a *spurious* naming (unit
  flights in alarm), and a mode confirmed on a unit that does not carry it on that flight a
  *spurious confirmation* (of all confirmations: each is one event per unit, mode and alarm).
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Iterator, Mapping, Sequence
from typing import Any

from server.phm.metrics import proportion_interval

from .bootstrap import mean_ci, nan_if_none, resamples
from .false_alarms import LEVEL
from .scoring import pattern_prognosis

__all__ = ["score_pattern", "score_concurrent"]


def _end(fault: Mapping[str, Any], last: int) -> int:
    return int(fault["end_flight"]) if fault.get("end_flight") is not None else last


def _fault_facts(fault: Mapping[str, Any], flights: Sequence[Mapping[str, Any]]
                 ) -> dict[str, Any]:
    onset, pos, mode = int(fault["onset_flight"]), fault["position"], fault["mode"]
    end = _end(fault, int(flights[-1]["index"]) if flights else onset)
    window = [f for f in flights if onset <= int(f["index"]) <= end]
    alarmed = next((int(f["index"]) for f in window if pos in f["units"]), None)
    named = next((int(f["index"]) for f in window
                  if mode in (f["units"].get(pos) or {}).get("modes", [])), None)
    confirmed = next((int(f["index"]) for f in flights if int(f["index"]) <= end
                      and _confirms(f["units"].get(pos) or {}, mode)), None)
    life = (int(fault["failure_flight"]) - onset if fault.get("failure_flight") is not None
            else float(fault["span_flights"]))
    return {"mode": mode, "position": pos, "onset": onset, "end": end,
            "outcome": fault["outcome"], "failure": fault.get("failure_flight"), "life": life,
            "alarmed": alarmed, "named": named, "confirmed": confirmed,
            "named_pct_life": None if named is None else 100.0 * (named - onset) / life}


def _confirms(unit: Mapping[str, Any], mode: str) -> bool:
    return unit.get("confirmed") == mode or mode in (unit.get("confirmed_others") or [])


def _named_at(flight: Mapping[str, Any] | None, faults: Sequence[Mapping[str, Any]]) -> bool:
    return flight is not None and all(
        f["mode"] in (flight["units"].get(f["position"]) or {}).get("modes", [])
        for f in faults)


def _unit_flights(trace: Mapping[str, Any]
                  ) -> Iterator[tuple[str, Mapping[str, Any], set[tuple[str, str]]]]:
    """Each unit in alarm on each flight: (its position, what it said, the (unit, mode)
    pairs the aircraft carries on that flight)."""
    carried = {int(f["index"]): {(x["position"], x["mode"]) for x in f["faults"]}
               for f in trace["truth"]["flights"]}
    for f in trace["flights"]:
        here = carried.get(int(f["index"]), set())
        for pos, unit in f["units"].items():
            yield pos, unit, here


def _spurious(trace: Mapping[str, Any]) -> tuple[int, int]:
    """(unit-flights in alarm naming a mode the unit does not carry, unit-flights in alarm)."""
    named = [any((pos, m) not in here for m in unit["modes"][1:])
             for pos, unit, here in _unit_flights(trace)]
    return sum(named), len(named)


def _confirmations(trace: Mapping[str, Any]) -> tuple[int, int]:
    """(confirmations of a mode the unit does not carry on that flight, confirmations)."""
    wrong = [(pos, m) not in here for pos, unit, here in _unit_flights(trace)
             for m in ([unit["confirmed"]] if unit.get("confirmed") else [])
             + list(unit.get("confirmed_others") or [])]
    return sum(wrong), len(wrong)


def _earlier_failure(trace: Mapping[str, Any], faults: Sequence[Mapping[str, Any]]
                     ) -> dict[str, Any] | None:
    """The first failure's prognostic metrics, its unit's RUL scored as a single fault's."""
    failed = sorted((f for f in faults if f["failure"] is not None),
                    key=lambda f: int(f["failure"]))
    if not failed:
        return None
    f = failed[0]
    pos = f["position"]
    flights = [{"index": int(x["index"]), "alarm": pos in x["units"],
                "new_alarms": sorted(p for p, u in x["units"].items() if u["new_alarm"]),
                "probs": (x["units"].get(pos) or {}).get("probs"),
                "fault_mode": (x["units"].get(pos) or {}).get("fault_mode"),
                "rul": (x["units"].get(pos) or {}).get("rul")}
               for x in trace["flights"] if int(x["index"]) <= int(f["failure"])]
    sub = {"id": trace["id"], "aircraft": trace["aircraft"], "mode": f["mode"],
           "position": pos, "onset": f["onset"], "failure": f["failure"],
           "horizon": trace["horizon"], "flights": flights}
    p = pattern_prognosis(sub)
    return {"mode": f["mode"], "position": pos, "ph": p["ph"], "ph_cone": p["ph_cone"],
            "ra": p["ra"], "detected_index": p["detected_index"],
            "modes_used": sorted({x["mode_used"] for x in p["predictions"] if x["mode_used"]})}


def score_pattern(trace: Mapping[str, Any]) -> dict[str, Any]:
    """One concurrent pattern's facts (see the module docstring)."""
    flights = trace["flights"]
    faults = [_fault_facts(f, flights) for f in trace["truth"]["faults"] if f["started"]]
    first = min(faults, key=lambda f: f["onset"])
    half = first["onset"] + 0.5 * first["life"]
    eligible = all(f["onset"] < half for f in faults)
    at_half = next((f for f in reversed(flights) if int(f["index"]) <= half), None)
    wrong, total = _spurious(trace)
    wrong_confirmed, confirmations = _confirmations(trace)
    return {"id": trace["id"], "combination": trace["combination"], "faults": faults,
            "half_flight": half, "eligible_at_half": eligible,
            "named_by_half": (all(f["named"] is not None and f["named"] <= half
                                  for f in faults) if eligible else None),
            "named_at_half": _named_at(at_half, faults) if eligible else None,
            "named_ever": all(f["named"] is not None for f in faults),
            "earlier_failure": _earlier_failure(trace, faults),
            "spurious_unit_flights": wrong, "unit_flights_in_alarm": total,
            "spurious_confirmations": wrong_confirmed, "confirmations": confirmations}


def _share(hits: int, n: int) -> dict[str, Any]:
    return {"hits": hits, "n": n, "share": hits / n if n else None,
            "interval": proportion_interval(hits, n, LEVEL) if n else None}


def _summary(rows: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    faults = [f for r in rows for f in r["faults"]]
    eligible = [r for r in rows if r["eligible_at_half"]]
    early = [r["earlier_failure"] for r in rows if r["earlier_failure"] is not None]
    idx = resamples(len(early))
    named_pct = [f["named_pct_life"] for f in faults if f["named_pct_life"] is not None]
    seconds = [max(r["faults"], key=lambda f: f["onset"]) for r in rows]
    second_delay = [f["named"] - f["onset"] for f in seconds if f["named"] is not None]
    return {"patterns": len(rows),
            "faults_alarmed": _share(sum(f["alarmed"] is not None for f in faults),
                                     len(faults)),
            "faults_named": _share(sum(f["named"] is not None for f in faults), len(faults)),
            "faults_confirmed": _share(sum(f["confirmed"] is not None for f in faults),
                                       len(faults)),
            "named_by_half": _share(sum(bool(r["named_by_half"]) for r in eligible),
                                    len(eligible)),
            "named_at_half": _share(sum(bool(r["named_at_half"]) for r in eligible),
                                    len(eligible)),
            "second_after_half": len(rows) - len(eligible),
            "named_ever": _share(sum(r["named_ever"] for r in rows), len(rows)),
            "named_pct_life_mean": (sum(named_pct) / len(named_pct) if named_pct
                                    else None),
            # the later fault: flights from its onset to its mode named on its unit
            "second_named_flights_mean": (sum(second_delay) / len(second_delay)
                                          if second_delay else None),
            "earlier_failure": {
                "n": len(early),
                **mean_ci("ph", [e["ph"] for e in early], idx),
                **mean_ci("ph_cone", [e["ph_cone"] for e in early], idx),
                **mean_ci("ra", [nan_if_none(e["ra"]) for e in early], idx)},
            "spurious": _share(sum(r["spurious_unit_flights"] for r in rows),
                               sum(r["unit_flights_in_alarm"] for r in rows)),
            "spurious_confirmations": _share(sum(r["spurious_confirmations"] for r in rows),
                                             sum(r["confirmations"] for r in rows))}


def _by_failing_mode(rows: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """The earlier failure's PH and RA per its mode: beside a single fault's of that mode."""
    by: dict[str, list[Mapping[str, Any]]] = defaultdict(list)
    for r in rows:
        if r["earlier_failure"] is not None:
            by[r["earlier_failure"]["mode"]].append(r["earlier_failure"])
    out = {}
    for mode, early in sorted(by.items()):
        idx = resamples(len(early))
        out[mode] = {"n": len(early), **mean_ci("ph", [e["ph"] for e in early], idx),
                     **mean_ci("ra", [nan_if_none(e["ra"]) for e in early], idx)}
    return out


def score_concurrent(traces: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """Per combination kind and over all: the shares with their exact 90 % intervals, the
    earlier failure's PH and RA with bootstrap intervals over patterns (also per the failing
    fault's mode); every pattern's facts under ``patterns``."""
    rows = [score_pattern(t) for t in traces]
    by: dict[str, list[dict[str, Any]]] = defaultdict(list)
    for r in rows:
        by[r["combination"]].append(r)
    return {"level": LEVEL, "all": _summary(rows),
            "combinations": {k: _summary(v) for k, v in sorted(by.items())},
            "earlier_failure_by_mode": _by_failing_mode(rows),
            "patterns": rows}
