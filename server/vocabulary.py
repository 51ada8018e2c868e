"""The project's shared vocabulary: actuator positions, fault modes, feature names, the
winglet-pair rule, the paper's reference figures, and the states of a flight, a job, an alarm
and a model version.

One owner for each of these facts; every other module (the simulator, the PHM chain, the
services, the dashboard) imports them from here. Pure Python, no dependencies, so that
``server.phm`` and ``sim_worker`` may import it without crossing a layer.
"""

from __future__ import annotations

from enum import StrEnum

__all__ = [
    "POSITIONS",
    "SIGNALS",
    "SENSOR_OF_SIGNAL",
    "SENSORS",
    "WINGLET_PAIR",
    "FAULT_MODES",
    "PROGRESSIVE",
    "SHARED_SIGNAL_PATH",
    "ABRUPT",
    "ACTUATOR_FEATURES",
    "GENERIC_FEATURES",
    "REWEAR_FEATURE",
    "position_features",
    "OWN_FEATURE",
    "MODE_NAMES",
    "FEATURE_LABELS",
    "PAPER_TABLE2",
    "is_winglet",
    "alarming_positions",
    "FlightStatus",
    "JobStatus",
    "StationStatus",
    "STATION_LIVE",
    "AlarmStatus",
    "ModelVersionStatus",
    "BASES",
    "CONDITION_KINDS",
]

#: actuator positions of the half-wing: two winglet-tab drives and the wingtip drive
POSITIONS: tuple[str, ...] = ("WL1", "WL2", "WT")
#: the two drives that share the winglet tab (active-standby: one drives, one stands by)
WINGLET_PAIR: tuple[str, str] = ("WL1", "WL2")

#: the recorded sensor signals of one actuator (flight-log v1 ``"<position>.<signal>"``):
#: phase currents [A], phase voltages [V], resolver shaft angle [rad], LVDT rod position [m]
SIGNALS: tuple[str, ...] = ("ia", "ib", "ic", "va", "vb", "vc", "theta", "x")

#: the sensor each signal comes from (the three phase currents share one current-sensor
#: chain's design, likewise the voltages); a sensor finding names the channel and its sensor
SENSOR_OF_SIGNAL: dict[str, str] = {"ia": "current", "ib": "current", "ic": "current",
                                    "va": "voltage", "vb": "voltage", "vc": "voltage",
                                    "theta": "resolver", "x": "lvdt"}
SENSORS: tuple[str, ...] = tuple(dict.fromkeys(SENSOR_OF_SIGNAL.values()))

#: the seven fault modes (paper section 4.2); an actuator carries at most one fault of each
FAULT_MODES: tuple[str, ...] = ("TTS", "DMD", "SE", "BDO", "MTEL", "MTWEAR", "REWEAR")
#: modes that progress from onset to a failure threshold (the prognosis runs on these)
PROGRESSIVE: tuple[str, ...] = ("TTS", "DMD", "MTEL", "MTWEAR", "REWEAR")
#: pairs of progressive modes of one actuator that share a signal path, so that one moves
#: the other's own feature: the screw's gap and the lubricant's drag in the mechanical
#: efficiency, a short and the magnets in the motor's current, the rod end's play and the
#: screw's gap in the LVDT
SHARED_SIGNAL_PATH: tuple[tuple[str, str], ...] = (
    ("MTWEAR", "MTEL"), ("TTS", "DMD"), ("REWEAR", "MTWEAR"))
#: modes imposed a priori at a constant severity (replace now, no RUL)
ABRUPT: tuple[str, ...] = tuple(m for m in FAULT_MODES if m not in PROGRESSIVE)

#: the six features computed per actuator (paper Table 1)
ACTUATOR_FEATURES: tuple[str, ...] = ("F_TTS", "F_DMD", "F_SE", "F_BDO", "F_MTEL", "F_MTWEAR")
#: the rod-end feature of a winglet drive: its rod end's play, read from the difference of
#: the two winglet LVDTs (the standby's against the active's)
REWEAR_FEATURE = "F_REWEAR"
#: the seven generic feature names (six per actuator plus the winglet drives' rod-end play)
GENERIC_FEATURES: tuple[str, ...] = ACTUATOR_FEATURES + (REWEAR_FEATURE,)
#: the paper's Table 1: one preferential feature per fault mode (tracked by the filter)
OWN_FEATURE: dict[str, str] = dict(zip(FAULT_MODES, GENERIC_FEATURES, strict=True))

#: plain names of the fault modes (the paper's Table 1), shown beside their codes
MODE_NAMES: dict[str, str] = {
    "TTS": "turn-to-turn short in the motor windings",
    "DMD": "magnet degradation",
    "SE": "static eccentricity of the rotor",
    "BDO": "open MOSFET base drive (inverter leg)",
    "MTEL": "screw efficiency loss, lubricant ageing",
    "MTWEAR": "wear-induced backlash of the ball screw",
    "REWEAR": "wear-induced backlash of the rod-end joints",
}

#: plain names of the generic health features (what each measures), shown beside their codes
FEATURE_LABELS: dict[str, str] = {
    "F_TTS": "winding-to-frame leakage",
    "F_DMD": "magnet flux deficit",
    "F_SE": "once-per-turn flux modulation",
    "F_BDO": "phase-voltage imbalance",
    "F_MTEL": "screw friction ratio",
    "F_MTWEAR": "screw gap, LVDT against motor shaft",
    "F_REWEAR": "rod-end play, standby LVDT against the active one",
}

#: the paper's Table 2: prognostic horizon [-] and relative accuracy [%] per progressive mode
PAPER_TABLE2: dict[str, tuple[float, float]] = {
    "TTS": (0.11, 64.3), "DMD": (0.55, 75.3), "MTEL": (0.15, 78.2), "MTWEAR": (0.82, 81.2),
    "REWEAR": (0.65, 79.3),
}


#: the simulated fleet's home bases, each with its own climate (sim_worker/fleet.py holds the
#: climates, sim_worker/data the monthly temperatures)
BASES: tuple[str, ...] = ("Turin", "Vancouver", "Abu Dhabi")

#: the test station's simulation conditions on an aircraft (server/services/station.py, flown
#: by sim_worker/conditions.py): the ambient temperature offset [K], the scenario's eq. (1)
#: load scale sigma_F and load offset sigma_F0 [N], its command scale sigma_x, and the base whose
#: climate the flight's ground temperature is drawn from
CONDITION_KINDS: tuple[str, ...] = ("ambient_offset", "load_scale", "load_offset",
                                    "command_scale", "base")


class FlightStatus(StrEnum):
    """Where an uploaded flight is. The values are the API's and the database's text (a CHECK
    constraint holds the column to them): renaming one is a migration and an API change."""

    RECEIVED = "received"
    QUEUED = "queued"
    ANALYZING = "analyzing"
    ANALYZED = "analyzed"
    #: failed decoding or coherence: kept for forensics, holds no slot (server/services/flights.py)
    REJECTED = "rejected"
    #: the analysis gave up after its last attempt, until an admin retries it
    FAILED = "failed"


class JobStatus(StrEnum):
    """Where a background job is (server/jobs/queue.py); the API's and the database's text,
    held by a CHECK constraint like the flight's."""

    QUEUED = "queued"
    RUNNING = "running"
    DONE = "done"
    #: failed its last attempt (or its worker vanished during it): never claimed again
    DEAD = "dead"


class StationStatus(StrEnum):
    """Where a test-station item (fault injection, sensor injection, condition) is; the API's
    and the database's text, held by a CHECK constraint like the flight's."""

    #: made by an operator, to start on its onset flight
    PENDING = "pending"
    #: being flown: the simulator has applied it to a flight
    ACTIVE = "active"
    #: ended by an operator, or by the replacement of the unit it sat on
    CANCELLED = "cancelled"
    #: a fault injection whose actuator reached the failure threshold
    FAILED = "failed"


#: the states in which a test-station item is live: a pending one starts on its onset flight,
#: an active one is being flown. The database holds one live item per slot by a partial unique
#: index (server/models.py, migrations 0013 and 0017)
STATION_LIVE: tuple[str, ...] = (StationStatus.PENDING.value, StationStatus.ACTIVE.value)


class AlarmStatus(StrEnum):
    """Where an alarm is in its handling (server/services/health.py): raised open, then
    acknowledged, then closed; the API's and the database's text, held by a CHECK constraint
    like the flight's."""

    OPEN = "open"
    ACKNOWLEDGED = "acknowledged"
    #: resolved (its resolution says how): it claims no urgency any more
    CLOSED = "closed"


class ModelVersionStatus(StrEnum):
    """Where a PHM model version is (server/services/models.py); the API's and the database's
    text, held by a CHECK constraint like the flight's."""

    #: its training job is queued or running
    TRAINING = "training"
    #: trained and stored: the only status that may be activated
    READY = "ready"
    #: the training gave up (the row keeps the error)
    FAILED = "failed"


def is_winglet(position: str | None) -> bool:
    """Whether a position is one of the winglet-tab pair."""
    return position in WINGLET_PAIR


def position_features(position: str) -> tuple[str, ...]:
    """The generic features monitored on the drive at ``position``: the six of every
    actuator, plus the rod-end play for a winglet drive (the wingtip drive has no partner
    LVDT to read its rod end against)."""
    return GENERIC_FEATURES if is_winglet(position) else ACTUATOR_FEATURES


def alarming_positions(mode: str, position: str | None, *,
                       pair_rod_ends: bool = False) -> set[str]:
    """Actuator positions expected to alarm for a fault of ``mode`` at ``position``: its own.
    Rod-end wear of a winglet drive is read on the flights it stands by; when both drives
    drive (``pair_rod_ends``: an active-active tab) each carries the pair's lost motion, which
    cannot tell the two rod ends apart, so both alarm. A healthy pattern (no position or mode
    ``"healthy"``) alarms nothing."""
    if position is None or mode not in FAULT_MODES:
        return set()
    if pair_rod_ends and mode == "REWEAR" and is_winglet(position):
        return set(WINGLET_PAIR)
    return {position}
