"""A campaign as the PHM chain's training and evaluation see it: patterns of flights, each
flight's features with its ground-truth labels (labels never reach the chain at run time).

Pure data; :mod:`server.campaigns` reads campaign directories into these."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from datetime import datetime
from typing import Any

from server.vocabulary import REWEAR_FEATURE, WINGLET_PAIR

from .features import FlightFeatures

__all__ = ["FlightRecord", "Pattern", "Campaign", "reads_rod_ends_as_pair", "is_healthy_flight",
           "healthy_flights"]


@dataclass
class FlightRecord:
    """One flight of a pattern with its features and labels."""

    flight: str
    index: int
    severity: float
    severity_norm: float
    true_rul_flights: float | None
    ground_temp_c: float | None
    features: FlightFeatures
    started_at: datetime | None = None  # take-off time, from the flight log's metadata


@dataclass
class Pattern:
    """One aircraft's sequence of flights: healthy, or a fault from onset to failure."""

    id: str
    aircraft: str
    mode: str
    position: str | None
    onset_flight: int | None
    failure_flight: int | None
    flights: list[FlightRecord] = field(default_factory=list)
    base: str | None = None  # the aircraft's home base
    #: design sensor study: {"sensor", "noise", "twin"}, the twin healthy pattern flown again
    #: with one sensor noisier (None for every other pattern)
    sensor_study: dict[str, Any] | None = None


@dataclass
class Campaign:
    kind: str
    seed: int
    patterns: list[Pattern]
    aircraft: list[dict[str, Any]]
    #: the design campaign's sensor-study patterns, kept apart: they are healthy actuators
    #: with noisier sensors, for :mod:`server.phm.sensor_health` only
    sensor_study: list[Pattern] = field(default_factory=list)


def reads_rod_ends_as_pair(p: Pattern) -> bool:
    """Whether both winglet drives carry a rod-end value on some flight of the pattern: an
    active-active tab, whose drives both carry the pair's lost motion."""
    names = [f"{w}.{REWEAR_FEATURE}" for w in WINGLET_PAIR]
    return any(all(math.isfinite(r.features.summaries[n].value) for n in names)
               for r in p.flights)


def is_healthy_flight(p: Pattern, r: FlightRecord) -> bool:
    """A flight of a healthy pattern, or of a fault pattern before the fault's onset."""
    if p.mode == "healthy":
        return True
    return p.onset_flight is not None and r.index < int(p.onset_flight)


def healthy_flights(campaign: Campaign) -> list[tuple[str, list[FlightFeatures]]]:
    """Healthy flight sequences ``(aircraft, flights in order)``: healthy patterns and the
    pre-onset flights of fault patterns."""
    out = []
    for p in campaign.patterns:
        seq = [r.features for r in p.flights if is_healthy_flight(p, r)]
        if seq:
            out.append((p.aircraft, seq))
    return out
