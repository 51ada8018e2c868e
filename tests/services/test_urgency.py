"""The urgency rule (server/services/urgency.py): buckets, their colours and the inbox order."""

from __future__ import annotations

from datetime import datetime, timedelta, timezone

from server.services.urgency import (
    ACT_WITHIN,
    ACT_WITHIN_MAX_FLIGHTS,
    DEFERRED,
    HEALTHY,
    MONITOR,
    REPLACE_NOW,
    deferral_active,
    sort_key,
    urgency,
)


def test_abrupt_fault_at_alarm_is_replace_now() -> None:
    for mode in ("BDO", "SE"):
        u = urgency(failed_at_flight=None, alarm_open=True, fault_mode=mode,
                    rul_low_flights=None)
        assert u.bucket == REPLACE_NOW and u.colour == "red", mode


def test_failed_is_replace_now_even_without_alarm_or_when_deferred() -> None:
    for alarm_open, deferred in ((False, False), (True, True)):
        u = urgency(failed_at_flight=120, alarm_open=alarm_open, fault_mode="TTS",
                    rul_low_flights=300.0, deferred=deferred)
        assert u.bucket == REPLACE_NOW and "120" in u.reason


def test_low_quantile_sets_act_within_else_monitor() -> None:
    u = urgency(failed_at_flight=None, alarm_open=True, fault_mode="MTWEAR",
                rul_low_flights=37.6)
    assert (u.bucket, u.within_flights, u.colour) == (ACT_WITHIN, 37, "amber")
    assert u.label == "act within 37 flights"
    edge = urgency(failed_at_flight=None, alarm_open=True, fault_mode="DMD",
                   rul_low_flights=float(ACT_WITHIN_MAX_FLIGHTS))
    assert edge.bucket == ACT_WITHIN
    for low in (ACT_WITHIN_MAX_FLIGHTS + 0.5, None):
        u = urgency(failed_at_flight=None, alarm_open=True, fault_mode="DMD",
                    rul_low_flights=low)
        assert u.bucket == MONITOR and u.colour == "yellow"


def test_under_one_flight_is_due_now_not_act_within_0() -> None:
    """Issue 57: "act within 0 flights" (amber) stood for the last flight before a failure."""
    for low in (0.0, 0.6, 0.999, -2.0):
        u = urgency(failed_at_flight=None, alarm_open=True, fault_mode="DMD",
                    rul_low_flights=low)
        assert (u.bucket, u.within_flights, u.colour, u.label) == (
            REPLACE_NOW, None, "red", "replace now"), low
        assert "due now" in u.reason
    one = urgency(failed_at_flight=None, alarm_open=True, fault_mode="DMD", rul_low_flights=1.0)
    assert (one.bucket, one.within_flights) == (ACT_WITHIN, 1)


def test_no_alarm_is_healthy_and_deferral_downgrades() -> None:
    assert urgency(failed_at_flight=None, alarm_open=False, fault_mode=None,
                   rul_low_flights=None).bucket == HEALTHY
    u = urgency(failed_at_flight=None, alarm_open=True, fault_mode="BDO", rul_low_flights=None,
                deferred=True)
    assert u.bucket == DEFERRED and u.colour == "grey"


def test_deferral_expires_by_flights_or_date() -> None:
    now = datetime(2027, 1, 1, tzinfo=timezone.utc)
    assert deferral_active(until_flight=15, until=None, flights_seen=14, now=now)
    assert not deferral_active(until_flight=15, until=None, flights_seen=15, now=now)
    assert deferral_active(until_flight=None, until=now + timedelta(days=1), flights_seen=0,
                           now=now)
    assert not deferral_active(until_flight=None, until=now, flights_seen=0, now=now)
    assert not deferral_active(until_flight=None, until=None, flights_seen=0, now=now)


def test_order_is_by_bucket_then_flights_then_confidence() -> None:
    def u(mode: str | None, low: float | None, failed: int | None = None):  # type: ignore[no-untyped-def]
        return urgency(failed_at_flight=failed, alarm_open=True, fault_mode=mode,
                       rul_low_flights=low)

    cases = {"false alarm, confident": (u("MTEL", 400.0), 0.999),
             "40 flights": (u("TTS", 40.0), 0.90),
             "12 flights": (u("DMD", 12.0), 0.85),
             "BDO": (u("BDO", None), 0.70),
             "failed": (u("MTWEAR", 90.0, failed=200), 0.50),
             "monitor, less confident": (u("MTEL", None), 0.60)}
    order = sorted(cases, key=lambda k: sort_key(*cases[k]))
    assert order == ["BDO", "failed", "12 flights", "40 flights", "false alarm, confident",
                     "monitor, less confident"]
