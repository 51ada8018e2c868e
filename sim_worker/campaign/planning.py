"""What a campaign flies: its fleet (:func:`fleet_for`), its patterns in manifest order
(:func:`plan_campaign`) and the order they run in (:func:`execution_order`), and per flight
its random stream, recording length and test-station conditions.

Every aircraft seed, pattern seed and flight seed derives from the campaign seed via
``numpy.random.SeedSequence`` with a fixed key (kind, aircraft, pattern, flight), never from
the worker that runs it.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Iterable
from dataclasses import dataclass, replace

import numpy as np

from server.vocabulary import POSITIONS, SENSORS, WINGLET_PAIR

from ..conditions import NO_CONDITIONS, Conditions
from ..faults import A_PRIORI, MODES, PROGRESSIVE
from ..fleet import FLEET_BASES, Aircraft, build_aircraft
from .scales import (
    SCALES,
    SENSOR_STUDY_FLIGHTS,
    SENSOR_STUDY_PATTERNS,
    STATION_ENVELOPE,
    ScaleConfig,
)
from .sensor_faults import SensorFault, canonical_sensor_faults, with_noise, with_sensor_noise

__all__ = ["fleet_for", "PatternSpec", "plan_campaign", "execution_order", "flight_rng",
           "recording_s", "block_conditions"]

_KIND_CODE = {"design": 1, "verification": 2}


def _seed(*key: int) -> int:
    return int(np.random.SeedSequence(list(key)).generate_state(1, dtype=np.uint64)[0] >> 1)


def fleet_for(kind: str, seed: int, *, bases: tuple[str, ...] | None = None,
              noise_scale: float = 1.0,
              sensor_faults: Iterable[SensorFault | str] = ()) -> list[Aircraft]:
    """The ten aircraft of a campaign; verification tails and seeds never equal design ones.

    ``bases`` (robustness studies) cycles the given bases over the ten aircraft instead of
    4 Turin / 3 Vancouver / 3 Abu Dhabi; ``noise_scale`` multiplies every sensor's noise
    (currents, voltages, resolver, LVDT; offsets and quantisation unchanged). A ``noise``
    sensor fault multiplies one position's noise of one sensor further; a ``drift`` leaves
    the fleet as rigged (it is flown per flight, see :func:`at_flight`). Tails and aircraft
    seeds depend on none of these.
    """
    code = _KIND_CODE[kind]
    prefix = "I-DSG" if kind == "design" else "I-VER"
    order = FLEET_BASES if not bases else tuple(bases[i % len(bases)]
                                                 for i in range(len(FLEET_BASES)))
    fleet = [build_aircraft(f"{prefix}{i + 1:02d}", base, _seed(seed, code, i))
             for i, base in enumerate(order)]
    if noise_scale != 1.0:
        fleet = [with_noise(a, noise_scale) for a in fleet]
    noisy = [f for f in canonical_sensor_faults(sensor_faults) if f.kind == "noise"]
    if noisy:
        fleet = [with_sensor_noise(a, noisy) for a in fleet]
    return fleet


@dataclass(frozen=True)
class PatternSpec:
    id: str
    number: int
    aircraft_index: int
    mode: str
    position: str | None
    n_flights: int  # healthy / a priori
    onset: int
    seed: int
    day_offset: float
    sensor_study: str | None = None  # the sensor flown noisier (design sensor study)
    twin: str | None = None  # the healthy pattern it repeats


def _sensor_study(specs: list[PatternSpec], healthy_patterns: int) -> list[PatternSpec]:
    """The sensor-study patterns of a design campaign: twins of its first healthy patterns."""
    out: list[PatternSpec] = []
    for si, sensor in enumerate(SENSORS):
        for j in range(SENSOR_STUDY_PATTERNS):
            twin = specs[(si * SENSOR_STUDY_PATTERNS + j) % healthy_patterns]
            out.append(replace(twin, id=f"D-sensor-{sensor}-{j + 1:02d}",
                               number=len(specs) + len(out), sensor_study=sensor,
                               twin=twin.id,
                               n_flights=min(twin.n_flights, SENSOR_STUDY_FLIGHTS)))
    return out


def _healthy_length(cfg: ScaleConfig, seed: int, code: int, j: int) -> int:
    """Flights of the ``j``-th healthy pattern: the scale's number, or a draw from its range
    that depends on the campaign's seed and kind and the pattern alone."""
    if isinstance(cfg.healthy_flights, int):
        return cfg.healthy_flights
    lo, hi = (int(v) for v in cfg.healthy_flights)
    return int(np.random.default_rng(_seed(seed, code, 3000 + j)).integers(lo, hi + 1))


def plan_campaign(kind: str, seed: int, scale: str, *, per_mode: int | None = None,
                  patterns_per_mode: int | None = None) -> list[PatternSpec]:
    """All patterns of the campaign, in manifest order. ``per_mode``: every healthy pattern
    but only the first ``per_mode`` patterns of each fault mode (0: the healthy ones alone),
    each numbered and seeded as in the whole campaign, so they fly the same flights.
    ``patterns_per_mode`` plans that many fault patterns per mode instead of the scale's (a
    campaign of its own: the patterns are numbered, and so seeded, differently)."""
    if kind not in _KIND_CODE:
        raise ValueError(f"kind must be one of {sorted(_KIND_CODE)}")
    cfg = SCALES[scale][kind]
    if patterns_per_mode is not None:
        cfg = replace(cfg, patterns_per_mode=patterns_per_mode)
    code = _KIND_CODE[kind]
    specs: list[PatternSpec] = []
    n_air = len(FLEET_BASES)

    def add(mode: str, position: str | None, ai: int, n_flights: int, onset: int, j: int) -> None:
        number = len(specs)
        pid = f"{kind[0].upper()}-{mode}-{j + 1:02d}"
        specs.append(PatternSpec(pid, number, ai, mode, position, n_flights, onset,
                                 _seed(seed, code, 1000 + number), day_offset=37.0 * number % 365))

    for j in range(cfg.healthy_patterns):
        add("healthy", None, j % n_air, _healthy_length(cfg, seed, code, j), 0, j)
    for m_i, mode in enumerate(MODES):
        for j in range(cfg.patterns_per_mode):
            ai = (j * 3 + m_i) % n_air
            # a rod end's play is read against the partner drive's LVDT: a winglet drive
            pos = (WINGLET_PAIR[j % 2] if mode == "REWEAR"
                   else POSITIONS[(j + m_i) % len(POSITIONS)])
            if mode in A_PRIORI:
                add(mode, pos, ai, cfg.apriori_flights, cfg.apriori_onset, j)
            else:
                add(mode, pos, ai, 0, cfg.lead_flights, j)
    if kind == "design" and cfg.healthy_patterns:
        specs += _sensor_study(specs, cfg.healthy_patterns)
    if per_mode is not None:
        # the sensor study belongs to the fault-pattern part of a design campaign
        specs = [s for s in specs if (s.mode == "healthy" and not (s.sensor_study and
                                                                  per_mode == 0))
                 or (s.mode != "healthy" and int(s.id.rsplit("-", 1)[1]) <= per_mode)]
    return specs


def execution_order(specs: list[PatternSpec]) -> list[PatternSpec]:
    """The order patterns are simulated in (results are re-ordered by pattern number and do
    not depend on it): the modes' k-th patterns together, round by round, so that a run
    stopped part way (:func:`snapshot_campaign`) holds about the same share of every mode;
    within a round the long fault-to-failure runs first, for load balance."""
    seen: Counter[tuple[str, bool]] = Counter()
    round_of: dict[int, int] = {}
    for s in sorted(specs, key=lambda s: s.number):
        group = (s.mode, s.sensor_study is not None)
        round_of[s.number] = seen[group]
        seen[group] += 1
    return sorted(specs, key=lambda s: (s.sensor_study is not None, round_of[s.number],
                                        s.mode not in PROGRESSIVE, s.number))


def flight_rng(spec: PatternSpec, index: int, stream: int) -> np.random.Generator:
    return np.random.default_rng([spec.seed, index, stream])


def recording_s(cfg: ScaleConfig, spec: PatternSpec, index: int) -> float:
    """The recording length of a rendered flight [s]: drawn from ``cfg.recordings_s`` with
    the flight's own seed (a sensor-study twin draws its twin's), else ``cfg.duration_s``."""
    if not cfg.recordings_s:
        return cfg.duration_s
    pick = flight_rng(spec, index, 5).integers(len(cfg.recordings_s))
    return float(cfg.recordings_s[int(pick)])


def block_conditions(cfg: ScaleConfig, spec: PatternSpec, index: int) -> Conditions:
    """The test-station conditions of a healthy pattern's flight: its block's draw (the first
    block nominal: the unit learns its reference as installed; later blocks under conditions
    with probability 1/2, each drawn log-uniformly over ``STATION_ENVELOPE``, the offset
    uniformly)."""
    if not cfg.condition_blocks or spec.mode != "healthy":
        return NO_CONDITIONS
    block = index // cfg.condition_blocks
    rng = np.random.default_rng([spec.seed, block, 6])
    if block == 0 or rng.random() < 0.5:
        return NO_CONDITIONS
    lo, hi = STATION_ENVELOPE["ambient_offset_k"]
    ambient = round(float(rng.uniform(lo, hi)), 1)

    def scale(name: str) -> float:
        low, high = STATION_ENVELOPE[name]
        return round(float(np.exp(rng.uniform(math.log(low), math.log(high)))), 3)

    load = scale("load_scale")
    return Conditions(ambient_offset_k=ambient, load_scale=load,
                      command_scale=scale("command_scale"))
