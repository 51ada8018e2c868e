"""Whether a decoded flight can be analysed: every problem found, as :class:`Issue` s."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from server.flightlog.format import NOMINAL_SAMPLE_RATE_HZ, FlightLog, Issue
from server.flightlog.limits import DEFAULT_LIMITS, PhysicalLimits
from server.vocabulary import POSITIONS, SIGNALS


def check_coherence(
    log: FlightLog,
    *,
    fleet_serials: Mapping[str, str] | None,
    limits: PhysicalLimits = DEFAULT_LIMITS,
) -> list[Issue]:
    """All coherence issues of a decoded log (empty list: the flight can be analysed).

    ``fleet_serials`` maps position -> serial installed on the aircraft; ``None`` means the
    aircraft is not registered.
    """
    issues: list[Issue] = []
    meta, ch = log.metadata, log.channels
    if fleet_serials is None:
        issues.append(Issue("unknown_aircraft", f"Aircraft '{meta.aircraft}' is not registered.",
                            {"aircraft": meta.aircraft}))
    else:
        wrong = {p: {"file": meta.actuator_serials.get(p), "installed": s}
                 for p, s in fleet_serials.items() if meta.actuator_serials.get(p) != s}
        if wrong:
            issues.append(Issue("serial_mismatch", "Actuator serials in the file do not match "
                                "those installed: " + ", ".join(sorted(wrong)) + ".",
                                {"positions": wrong}))

    n = log.n_samples
    bad_len = sorted(k for k, v in ch.items() if v.ndim != 1 or v.shape[0] != n)
    if bad_len:
        issues.append(Issue("unreadable", "Channels have different lengths.",
                            {"channels": bad_len}))
        return issues

    non_finite = sorted(k for k, v in ch.items() if not np.isfinite(v).all())
    if non_finite:
        issues.append(Issue("non_finite", f"{len(non_finite)} channel(s) hold NaN or infinite "
                            "values: " + ", ".join(non_finite[:6]) + ".",
                            {"channels": non_finite}))

    nominal_dt = 1.0 / NOMINAL_SAMPLE_RATE_HZ
    t = ch["t"]
    if n < 2:
        issues.append(Issue("too_short", "The recording has fewer than two samples.",
                            {"samples": n}))
        return issues
    dt = np.diff(t)
    finite_dt = dt[np.isfinite(dt)]
    if (finite_dt <= 0).any():
        first = int(np.argmax(dt <= 0))
        issues.append(Issue("time_not_monotonic", "Time does not increase strictly (first at "
                            f"sample {first + 1}).", {"first_index": first + 1}))
    gaps = np.flatnonzero(finite_dt > (limits.max_missed_samples + 1.5) * nominal_dt)
    if gaps.size:
        issues.append(Issue("time_gap", f"{gaps.size} gap(s) of more than "
                            f"{limits.max_missed_samples} missed samples (first at t = "
                            f"{float(t[gaps[0]]):.3f} s).", {"count": int(gaps.size),
                                                             "first_t_s": float(t[gaps[0]])}))
    duration = float(t[-1] - t[0]) if np.isfinite(t[[0, -1]]).all() else 0.0
    if duration > 0:
        measured = (n - 1) / duration
        for label, rate in (("measured", measured), ("declared", meta.sample_rate_hz)):
            if abs(rate / NOMINAL_SAMPLE_RATE_HZ - 1.0) > limits.sample_rate_tolerance:
                issues.append(Issue("sample_rate_off", f"The {label} sample rate {rate:.2f} Hz is "
                                    f"more than {limits.sample_rate_tolerance:.0%} off "
                                    f"{NOMINAL_SAMPLE_RATE_HZ:.0f} Hz.",
                                    {label + "_hz": rate, "nominal_hz": NOMINAL_SAMPLE_RATE_HZ}))
    if duration < limits.min_duration_s:
        issues.append(Issue("too_short", f"The recording lasts {duration:.2f} s; at least "
                            f"{limits.min_duration_s:.0f} s are needed for a feature window.",
                            {"duration_s": duration, "min_s": limits.min_duration_s}))

    with np.errstate(invalid="ignore"):
        over_current = sorted(
            f"{p}.{s}" for p in POSITIONS for s in ("ia", "ib", "ic")
            if np.nanmax(np.abs(ch[f"{p}.{s}"])) > limits.max_current_a)
        over_stroke = sorted(f"{p}.x" for p in POSITIONS
                             if np.nanmax(np.abs(ch[f"{p}.x"])) > limits.max_abs_position_m)
    if over_current:
        issues.append(Issue("current_out_of_range", "Phase currents beyond "
                            f"{limits.max_current_a:.1f} A (3x rated): " + ", ".join(over_current)
                            + ".", {"channels": over_current, "limit_a": limits.max_current_a}))
    if over_stroke:
        issues.append(Issue("position_out_of_range", "Rod positions beyond the stroke "
                            f"(+-{limits.max_abs_position_m * 1e3:.0f} mm): "
                            + ", ".join(over_stroke) + ".",
                            {"channels": over_stroke, "limit_m": limits.max_abs_position_m}))

    stuck = []
    for p in POSITIONS:
        spans = {s: float(np.ptp(ch[f"{p}.{s}"])) for s in SIGNALS}
        cmd = ch.get(f"{p}.x_cmd")
        commanded = (float(np.ptp(cmd)) > 0) if cmd is not None else any(spans.values())
        if commanded:
            stuck += [f"{p}.{s}" for s, span in spans.items() if span == 0.0]
    if stuck:
        issues.append(Issue("stuck_sensor", "Sensors that never change while the actuator is "
                            "commanded: " + ", ".join(stuck) + ".", {"channels": stuck}))
    return issues
