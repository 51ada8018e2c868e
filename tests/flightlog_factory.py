"""Small, valid flight logs for service tests (the simulator makes the realistic ones).

Signals are smooth sinusoids within the physical limits: a slow rod motion per actuator, the
phase currents and voltages of a motor following it, so every coherence check passes.
"""

from __future__ import annotations

from datetime import datetime, timezone

import numpy as np

from server.flightlog import POSITIONS, FlightLog, FlightMetadata, write_parquet

SERIALS = {"WL1": "SN-WL1-{tail}", "WL2": "SN-WL2-{tail}", "WT": "SN-WT-{tail}"}


def serials_for(tail: str) -> dict[str, str]:
    return {p: s.format(tail=tail) for p, s in SERIALS.items()}


def make_log(tail: str = "T001", flight: str = "F0001", *, duration_s: float = 12.0,
             seed: int = 0, serials: dict[str, str] | None = None) -> FlightLog:
    rng = np.random.default_rng(seed)
    n = int(duration_s * 800)
    t = np.arange(n) / 800.0
    channels: dict[str, np.ndarray] = {"t": t}
    lead = 0.005
    for k, p in enumerate(POSITIONS):
        x = 0.01 * np.sin(2 * np.pi * 0.2 * t + k)
        theta = x / lead * 2 * np.pi
        elec = 4 * theta
        amp = 3.0 + rng.normal(0, 0.05)
        for j, ph in enumerate("abc"):
            shift = 2 * np.pi * j / 3
            channels[f"{p}.i{ph}"] = amp * np.sin(elec - shift) + rng.normal(0, 0.02, n)
            channels[f"{p}.v{ph}"] = 20 * np.sin(elec - shift + 0.3) + rng.normal(0, 0.2, n)
        channels[f"{p}.theta"] = theta
        channels[f"{p}.x"] = x + rng.normal(0, 1e-6, n)
        channels[f"{p}.x_cmd"] = x
    channels["T_amb"] = np.full(n, 15.0)
    meta = FlightMetadata(aircraft=tail, flight=flight,
                          started_at=datetime(2026, 5, 1, 8, 0, tzinfo=timezone.utc),
                          block_hours=1.7, sample_rate_hz=800.0,
                          actuator_serials=serials or serials_for(tail), source="tests")
    return FlightLog(meta, {k: np.asarray(v) for k, v in channels.items()})


def make_parquet(tail: str = "T001", flight: str = "F0001", **kwargs: object) -> bytes:
    return write_parquet(make_log(tail, flight, **kwargs))  # type: ignore[arg-type]
