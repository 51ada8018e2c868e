"""Which stored features are still valid: the feature code's outputs on a fixed set of canary
flights, digested.

A campaign's ``phm_features.json`` holds every flight's features; streamed campaigns keep no
flight log to compute them again. Keying that cache on a version string made every stored
campaign unreadable at each bump, even where a refactor moved no feature. The key is instead
what the features *are* on the canaries: ten short flights of one aircraft (healthy, each
fault mode at 60 % of its threshold on a varied position, one flight active-active, one under
the station's conditions), simulated with fixed seeds and analysed with the service's own
:func:`server.phm.recording.log_features`. A change that moves a feature or a signal-quality
figure on any of them changes the digest; a refactor that moves none keeps every campaign.

Values are rounded to :data:`SIGNIFICANT_DIGITS` before hashing, so the last bits a different
CPU's fused multiply-adds leave in the flights do not invalidate a campaign moved between
machines; a change smaller than that on every canary is taken for no change. A change of the
simulator that moves the canary flights also changes the digest: stored campaigns are then
recomputed or refused, never wrongly reused.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from datetime import datetime, timezone
from typing import Any

from server.phm.features import FeatureConfig
from server.phm.recording import log_features

__all__ = ["CANARY_DURATION_S", "SIGNIFICANT_DIGITS", "canary_digest"]

#: each canary's recording [s]: long enough for every feature's windows (cruise, reversals)
CANARY_DURATION_S = 30.0
#: digits kept of each value before hashing (about 1e-10 relative)
SIGNIFICANT_DIGITS = 10
_TAIL = "I-CANARY"
_SEED = 20261205


@dataclass(frozen=True)
class _Canary:
    mode: str
    position: str | None
    active_active: bool = False
    station_conditions: bool = False


# every fault mode once, on each position; the healthy flight once per winglet mode and once
# under conditions at the station's bounds
_CANARIES = (
    _Canary("healthy", None),
    _Canary("healthy", None, active_active=True),
    _Canary("healthy", None, station_conditions=True),
    _Canary("TTS", "WL1"),
    _Canary("DMD", "WT"),
    _Canary("SE", "WL2", active_active=True),
    _Canary("BDO", "WT"),
    _Canary("MTEL", "WL1"),
    _Canary("MTWEAR", "WT"),
    _Canary("REWEAR", "WL1", active_active=True),
)


def _fly(canary: _Canary, index: int) -> Any:
    """The canary's flight log (the simulator is imported here: the service needs it only to
    check a stored campaign)."""
    import numpy as np

    from sim_worker import build_aircraft, simulate_flight
    from sim_worker.conditions import NO_CONDITIONS, Conditions
    from sim_worker.faults import fault_at
    from sim_worker.fleet import WingletMode

    aircraft = build_aircraft(_TAIL, "Turin", seed=_SEED)
    fault = fault_at(canary.mode, canary.position, 0.6)
    mode = WingletMode.ACTIVE_ACTIVE if canary.active_active else WingletMode.ACTIVE_STANDBY
    conditions = Conditions(ambient_offset_k=-30.0, load_scale=2.0, command_scale=2.0) \
        if canary.station_conditions else NO_CONDITIONS
    log, _ = simulate_flight(aircraft, fault, index, np.random.default_rng([_SEED, index]),
                             flight_id=f"CANARY-{index:02d}", duration_s=CANARY_DURATION_S,
                             started_at=datetime(2026, 6, 1, 8, tzinfo=timezone.utc),
                             winglet_mode=mode, conditions=conditions)
    return log


def _rounded(value: Any) -> Any:
    if isinstance(value, float):
        return float(f"{value:.{SIGNIFICANT_DIGITS}g}")
    if isinstance(value, dict):
        return {k: _rounded(v) for k, v in sorted(value.items())}
    if isinstance(value, list | tuple):
        return [_rounded(v) for v in value]
    return value


def canary_digest(config: FeatureConfig | None = None) -> str:
    """The digest of every canary's features and signal-quality figures under ``config``
    (default: today's): equal digests, interchangeable features. About 2 s, once a process
    for each configuration."""
    cfg = config or FeatureConfig()
    key = repr(cfg)  # the configuration holds dicts: no hash of its own
    if key not in _DIGESTS:
        _DIGESTS[key] = _digest(cfg)
    return _DIGESTS[key]


_DIGESTS: dict[str, str] = {}


def _digest(cfg: FeatureConfig) -> str:
    outputs = [log_features(_fly(c, i), config=cfg, ground_temp_c=15.0).to_dict()
               for i, c in enumerate(_CANARIES)]
    text = json.dumps(_rounded(outputs), sort_keys=True, allow_nan=True)
    return hashlib.sha256(text.encode()).hexdigest()[:32]
