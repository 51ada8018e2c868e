"""What a campaign flies: its fleet (:func:`fleet_for`), its patterns in manifest order
(:func:`plan_campaign`) and the order they run in (:func:`execution_order`), and per flight
its random stream, recording length and test-station conditions.

Every aircraft seed, pattern seed and flight seed derives from the campaign seed via
``numpy.random.SeedSequence`` with a fixed key (kind, aircraft, pattern, flight), never from
the worker that runs it.

A ``concurrent`` campaign flies two progressive faults on one aircraft per pattern, one
pattern per :data:`COMBINATIONS` kind in turn: two modes of one actuator that share a signal
path (MTWEAR+MTEL: the screw's friction and play; TTS+DMD: the winding's back-EMF and current;
REWEAR+MTWEAR: the lost motion between motor and surface), or two actuators of one aircraft
(the wingtip and a winglet drive; both winglet drives, active and standby in turn). The
second fault starts a drawn number of flights after the first (:data:`ONSET_GAP` of the
first's expected span), each fault with its own span drawn by the scale's span law.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Iterable
from dataclasses import dataclass, replace

import numpy as np

from server.vocabulary import POSITIONS, SENSORS, SHARED_SIGNAL_PATH, WINGLET_PAIR

from ..conditions import NO_CONDITIONS, Conditions
from ..faults import A_PRIORI, MODES, PROGRESSIVE, draw_span
from ..fleet import FLEET_BASES, Aircraft, build_aircraft
from .scales import (
    SENSOR_STUDY_FLIGHTS,
    SENSOR_STUDY_PATTERNS,
    STATION_ENVELOPE,
    ScaleConfig,
    kind_config,
)
from .sensor_faults import SensorFault, canonical_sensor_faults, with_noise, with_sensor_noise

__all__ = ["KINDS", "fleet_for", "PatternSpec", "PlannedFault", "Combination", "COMBINATIONS",
           "ONSET_GAP", "PLACES", "plan_campaign", "execution_order", "flight_rng",
           "recording_s", "block_conditions"]

#: each kind's seed stream (a key of every seed it draws): kinds never share a seed
_KIND_CODE = {"design": 1, "verification": 2, "concurrent": 3}
#: the kinds of campaign
KINDS: tuple[str, ...] = tuple(_KIND_CODE)
_TAIL_PREFIX = {"design": "I-DSG", "verification": "I-VER", "concurrent": "I-CON"}
#: where campaigns place each mode: a rod end's play is read against the partner drive's
#: LVDT, so rod-end wear goes on a winglet drive (the wingtip's lone drive has no partner)
PLACES: dict[str, tuple[str, ...]] = {m: (WINGLET_PAIR if m == "REWEAR" else POSITIONS)
                                      for m in MODES}
#: the second fault of a concurrent pattern starts this fraction of the first fault's expected
#: span after it (drawn uniformly): both then progress together for most of the first's life
ONSET_GAP = (0.1, 0.5)


@dataclass(frozen=True)
class PlannedFault:
    """One fault of a concurrent pattern: where, from which flight, and its expected span."""

    mode: str
    position: str
    onset: int
    span_flights: float


@dataclass(frozen=True)
class Combination:
    """A kind of concurrent pattern: its two modes (None: drawn per pattern among the
    progressive modes each position can take) and the position pairs its patterns cycle
    over (the same position twice: two modes on one actuator)."""

    name: str  # the manifest's "mode" of its patterns (their ids write "+" as "_")
    modes: tuple[str, str] | None
    positions: tuple[tuple[str, str], ...]


def _same_unit(modes: tuple[str, str]) -> Combination:
    """Two modes sharing a signal path on one actuator, on every position that takes both."""
    where = WINGLET_PAIR if "REWEAR" in modes else POSITIONS  # a rod end: winglet drives only
    return Combination("+".join(modes), modes, tuple((p, p) for p in where))


#: the concurrent campaign's kinds of pattern, in manifest order
COMBINATIONS: tuple[Combination, ...] = (
    *(_same_unit(pair) for pair in SHARED_SIGNAL_PATH),
    Combination("WT+WL", None, (("WT", "WL1"), ("WT", "WL2"))),
    Combination("WL1+WL2", None, (WINGLET_PAIR,)),
)


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
    prefix = _TAIL_PREFIX[kind]
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
    #: a concurrent pattern's faults, by onset (``mode`` names its combination kind)
    faults: tuple[PlannedFault, ...] = ()


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
                  patterns_per_mode: int | None = None,
                  step_flights: int | None = None) -> list[PatternSpec]:
    """All patterns of the campaign, in manifest order. ``per_mode``: every healthy pattern
    but only the first ``per_mode`` patterns of each fault mode (0: the healthy ones alone),
    each numbered and seeded as in the whole campaign, so they fly the same flights.
    ``patterns_per_mode`` plans that many fault patterns per mode (concurrent: per combination
    kind) instead of the scale's (a campaign of its own: the patterns are numbered, and so
    seeded, differently). ``step_flights``: the length of the step faults' (SE, BDO) patterns
    instead of the scale's (their first flights are the same)."""
    if kind not in KINDS:
        raise ValueError(f"kind must be one of {KINDS}")
    cfg = kind_config(scale, kind)
    if patterns_per_mode is not None:
        cfg = replace(cfg, patterns_per_mode=patterns_per_mode)
    if step_flights is not None:
        cfg = replace(cfg, apriori_flights=step_flights)
    code = _KIND_CODE[kind]
    if kind == "concurrent":
        return _plan_concurrent(cfg, seed, code, per_mode)
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


def _plan_concurrent(cfg: ScaleConfig, seed: int, code: int, per_mode: int | None
                     ) -> list[PatternSpec]:
    """The concurrent campaign's patterns: ``cfg.patterns_per_mode`` of each combination kind
    (``per_mode``: the first that many), each on its aircraft and positions in turn, both
    orders of its modes in turn."""
    specs: list[PatternSpec] = []
    n = cfg.patterns_per_mode if per_mode is None else min(per_mode, cfg.patterns_per_mode)
    for c_i, combo in enumerate(COMBINATIONS):
        for j in range(n):  # each pattern's draws its own: a part flies the whole's flights
            number = c_i * cfg.patterns_per_mode + j
            faults = _concurrent_faults(combo, j, cfg, np.random.default_rng(
                _seed(seed, code, 2000 + number)))
            specs.append(PatternSpec(
                f"C-{combo.name.replace('+', '_')}-{j + 1:02d}",  # no "+" in flight codes
                number, (j * 3 + c_i) % len(FLEET_BASES), combo.name, None, 0,
                faults[0].onset, _seed(seed, code, 1000 + number),
                day_offset=37.0 * number % 365, faults=faults))
    return specs


def _concurrent_faults(combo: Combination, j: int, cfg: ScaleConfig,
                       rng: np.random.Generator) -> tuple[PlannedFault, PlannedFault]:
    """The two faults of the ``j``-th pattern of ``combo``: its positions (cycled), the order
    of its faults (alternating), drawn modes where the kind leaves
    them open, each span by the scale's law and the second onset a drawn gap later."""
    pair = combo.positions[j % len(combo.positions)]
    if combo.modes is None:
        modes = tuple(str(rng.choice([m for m in PROGRESSIVE if p in PLACES[m]])) for p in pair)
    else:
        modes = combo.modes
    # the order alternates pattern by pattern; over an even number of pairs it also steps
    # once a round, so that every pair is flown in both orders (6 patterns cover 3 pairs)
    pairs = len(combo.positions)
    order = (0, 1) if (j + (j // pairs if pairs % 2 == 0 else 0)) % 2 == 0 else (1, 0)
    spans = [draw_span(rng, cfg.span_flights, cfg.span_draw) for _ in order]
    gap = max(1, round(float(rng.uniform(*ONSET_GAP)) * spans[0]))
    first, second = order
    return (PlannedFault(modes[first], pair[first], cfg.lead_flights, spans[0]),
            PlannedFault(modes[second], pair[second], cfg.lead_flights + gap, spans[1]))


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
