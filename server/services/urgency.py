"""The urgency rule: one owner for what the fleet grid's colour and the alarm inbox's order
say (the page and the API read it from here; ``docs/DASHBOARD.md`` states it).

Buckets, most urgent first::

    replace_now   the unit has failed (a state, until it is replaced), an open alarm is of
                  an abrupt mode (SE, BDO: no degradation to ride out), or the
                  low RUL quantile (5 %) is under one flight: due now            -> red
    act_within    the low RUL quantile (5 %) of the latest prognosis is 1 to
                  ACT_WITHIN_MAX_FLIGHTS: act within that many flights          -> amber
    monitor       any other open alarm (no prognosis yet, or RUL 5 % beyond it)  -> yellow
    deferred      an open alarm deferred by maintenance, until its deferral ends -> grey
    healthy       no open alarm                                                  -> green

A failed unit is ``replace_now`` whatever a deferral says; a deferral hides the other buckets
until its flight count or date is reached, then the alarm is back in its own bucket and the
expiry is shown. Within a bucket: ``act_within`` by its flights (fewest first), then by
detection confidence (highest first).
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import datetime

from server.vocabulary import ABRUPT

__all__ = ["REPLACE_NOW", "ACT_WITHIN", "MONITOR", "DEFERRED", "HEALTHY", "BUCKETS", "COLOUR",
           "RUL_LOW_QUANTILE", "ACT_WITHIN_MAX_FLIGHTS", "Urgency", "urgency", "deferral_active",
           "sort_key", "flights"]

REPLACE_NOW = "replace_now"
ACT_WITHIN = "act_within"
MONITOR = "monitor"
DEFERRED = "deferred"
HEALTHY = "healthy"
#: most urgent first: the inbox order and the rank of a grid cell
BUCKETS = (REPLACE_NOW, ACT_WITHIN, MONITOR, DEFERRED, HEALTHY)
COLOUR = {REPLACE_NOW: "red", ACT_WITHIN: "amber", MONITOR: "yellow", DEFERRED: "grey",
          HEALTHY: "green"}

#: the RUL quantile urgency is read from: the 5 % quantile, a pessimistic RUL
RUL_LOW_QUANTILE = 0.05
#: a 5 % RUL quantile at or below this many flights asks for action within that many flights
#: (about two weeks of a regional fleet's flying; beyond it the alarm is watched)
ACT_WITHIN_MAX_FLIGHTS = 50


@dataclass(frozen=True)
class Urgency:
    bucket: str
    within_flights: int | None = None  # act_within: act within this many flights
    reason: str = ""

    @property
    def colour(self) -> str:
        return COLOUR[self.bucket]

    @property
    def rank(self) -> int:
        return BUCKETS.index(self.bucket)

    @property
    def label(self) -> str:
        if self.bucket == ACT_WITHIN:
            return f"act within {flights(self.within_flights)}"
        return self.bucket.replace("_", " ")


def flights(n: int | None) -> str:
    """``"1 flight"``, ``"12 flights"``."""
    return f"{n} flight" if n == 1 else f"{n} flights"


def deferral_active(*, until_flight: int | None, until: datetime | None, flights_seen: int,
                    now: datetime) -> bool:
    """A deferral holds while neither its flight count nor its date is reached."""
    if until_flight is None and until is None:
        return False
    if until_flight is not None and flights_seen >= until_flight:
        return False
    return not (until is not None and now >= until)


def urgency(*, failed_at_flight: int | None, alarm_open: bool, fault_mode: str | None,
            rul_low_flights: float | None, deferred: bool = False) -> Urgency:
    """The bucket of one actuator (or one of its alarms): the rule stated above."""
    if failed_at_flight is not None:
        return Urgency(REPLACE_NOW, reason=f"failed at flight {failed_at_flight}")
    if not alarm_open:
        return Urgency(HEALTHY)
    if deferred:
        return Urgency(DEFERRED, reason="deferred by maintenance")
    if fault_mode in ABRUPT:
        return Urgency(REPLACE_NOW, reason=f"{fault_mode} is an abrupt fault")
    if rul_low_flights is not None and rul_low_flights <= ACT_WITHIN_MAX_FLIGHTS:
        n = max(int(rul_low_flights), 0)
        if n == 0:  # "act within 0 flights" is before the next flight: now
            return Urgency(REPLACE_NOW, reason=f"RUL {RUL_LOW_QUANTILE:.0%} quantile under "
                           "1 flight: due now")
        return Urgency(ACT_WITHIN, within_flights=n,
                       reason=f"RUL {RUL_LOW_QUANTILE:.0%} quantile {flights(n)}")
    return Urgency(MONITOR, reason="alarm open; RUL not short")


def sort_key(u: Urgency, confidence: float) -> tuple[int, float, float]:
    """Most urgent first: bucket, then fewest flights to act within, then confidence."""
    within = float(u.within_flights) if u.within_flights is not None else float("inf")
    return (u.rank, within, -confidence)
