"""The campaign scales: what a design, verification or concurrent campaign of each scale flies
(:class:`ScaleConfig`, :data:`SCALES`; concurrent campaigns at the ``ci`` and ``quick`` scales),
the test station's envelope and the design's sensor study, and a scale with a run's overrides
checked (:func:`scale_config`).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, replace

from ..faults import ENVELOPE_FLIGHTS, SPAN_DRAWS, SPAN_FLIGHTS

__all__ = ["ScaleConfig", "SCALES", "kind_config", "MAX_FLIGHTS", "STATION_ENVELOPE",
           "SENSOR_STUDY_PATTERNS", "SENSOR_STUDY_NOISE", "SENSOR_STUDY_FLIGHTS", "scale_config"]

MAX_FLIGHTS = 2000  # a fault-to-failure run stops here at the latest
_MAX_SPAN = 1500.0  # largest expected span a user may ask for [flights], under MAX_FLIGHTS


@dataclass(frozen=True)
class ScaleConfig:
    duration_s: float  # s of reference actuator activity per recording
    healthy_patterns: int  # number of healthy patterns (spread over the aircraft)
    #: flights per healthy pattern: a number, or a (low, high) range each pattern draws its
    #: length from (uniform integers, from the pattern's seed): the paper's healthy cycles
    #: ran as long as its degradation patterns (section 5.1)
    healthy_flights: int | tuple[int, int]
    #: degradation patterns per fault mode (a concurrent campaign: per combination kind)
    patterns_per_mode: int
    #: render every k-th flight of a fault-to-failure run; odd, so the rendered flights take
    #: both winglet roles (the active drive alternates by flight: an even step would read a
    #: faulty winglet drive in one role only, never its motor features or never its play)
    render_every: int
    apriori_flights: int  # flights per SE / BDO pattern
    apriori_onset: int  # index of the first faulty flight of an SE / BDO pattern
    #: healthy flights (all rendered) before a progressive fault starts: the actuator's
    #: in-service history after installation, from which detection learns its own reference
    lead_flights: int = 8
    #: range of the expected fault-to-failure span drawn per pattern [flights]
    span_flights: tuple[float, float] = SPAN_FLIGHTS
    #: how a pattern draws its span from ``span_flights``: "uniform", or "log" (log-uniform,
    #: as many runs between 30 and 100 flights as between 300 and 1000: a design campaign
    #: over the test station's whole envelope)
    span_draw: str = "uniform"
    #: recording lengths [s] each rendered flight draws from (uniformly, from the flight's
    #: seed); empty: every flight ``duration_s``. A fleet's recordings vary in length, and a
    #: feature's scatter with them (server.phm.detection: the evidence of a flight)
    recordings_s: tuple[float, ...] = ()
    #: healthy patterns fly in blocks of this many flights, each after the first under the
    #: test station's conditions with probability 1/2 (drawn over ``STATION_ENVELOPE``); 0:
    #: never. Training then learns the conditions as covariates, steps within a unit's life
    #: included, as an operator sets them
    condition_blocks: int = 0


#: the test station's conditions a design's healthy blocks are drawn over (log-uniformly for
#: the scales): inside the ranges the station accepts (server.schemas), and out to the
#: bounds an operator is promised quiet at (ambient -30/+30 K, load x0.5/x2, command x2)
STATION_ENVELOPE: dict[str, tuple[float, float]] = {
    "ambient_offset_k": (-30.0, 30.0), "load_scale": (0.5, 2.0), "command_scale": (0.5, 2.0)}
#: the design campaign's sensor study: per sensor, this many of its healthy patterns flown
#: again with that sensor's noise multiplied by SENSOR_STUDY_NOISE on every actuator (the same
#: flights, seeds and noise draws as their twins): training learns from the pairs what a
#: noisier sensor does to each feature, loops included (server.phm.sensor_health)
SENSOR_STUDY_PATTERNS = 2
SENSOR_STUDY_NOISE = 2.0
#: a study pattern flies the first this many flights of its twin: the pairs measure a noise
#: ratio, which a few thousand paired flights pin down; a long healthy life adds no more
SENSOR_STUDY_FLIGHTS = 50
SCALES: dict[str, dict[str, ScaleConfig]] = {
    # Quick scale: big enough for honest statistics in CI (>= 250 healthy verification
    # flights on 10 aircraft, >= 3 patterns per mode), small enough for ~1 min per campaign.
    "quick": {
        "design": ScaleConfig(duration_s=60.0, healthy_patterns=10, healthy_flights=12,
                              patterns_per_mode=6, render_every=21, apriori_flights=6,
                              apriori_onset=2, span_flights=ENVELOPE_FLIGHTS, span_draw="log"),
        "verification": ScaleConfig(duration_s=60.0, healthy_patterns=10, healthy_flights=25,
                                    patterns_per_mode=3, render_every=21, apriori_flights=6,
                                    apriori_onset=2),
        # two faults at once on the verification's spans, every flight rendered (the ground
        # truth of both faults is read flight by flight)
        "concurrent": ScaleConfig(duration_s=60.0, healthy_patterns=0, healthy_flights=0,
                                  patterns_per_mode=3, render_every=1, apriori_flights=0,
                                  apriori_onset=0),
    },
    "paper": {
        "design": ScaleConfig(duration_s=120.0, healthy_patterns=10, healthy_flights=50,
                              patterns_per_mode=10, render_every=11, apriori_flights=8,
                              apriori_onset=2),
        "verification": ScaleConfig(duration_s=120.0, healthy_patterns=25, healthy_flights=4,
                                    patterns_per_mode=25, render_every=21, apriori_flights=8,
                                    apriori_onset=2),
    },
    # The paper's protocol (section 4.3): every flight of every pattern rendered, 25 patterns
    # per mode on 10 unseen aircraft; meant to be streamed (features kept, raw logs sampled).
    # Healthy cycles as long as the fault runs (150-400 flights, section 5.1): two flights a
    # day, so a cycle spans 2.5-7 months of one base's seasons; the design's ten run half a
    # year each (300-400 flights), starting in different months, so training sees every
    # season at every base and both winglet roles over months of service.
    "protocol": {
        "design": ScaleConfig(duration_s=120.0, healthy_patterns=10,
                              healthy_flights=(300, 400),
                              patterns_per_mode=10, render_every=1, apriori_flights=8,
                              apriori_onset=2, span_flights=ENVELOPE_FLIGHTS, span_draw="log"),
        "verification": ScaleConfig(duration_s=120.0, healthy_patterns=25,
                                    healthy_flights=(150, 400),
                                    patterns_per_mode=25, render_every=1, apriori_flights=8,
                                    apriori_onset=2),
    },
    # The shipped model's design (server/data/demo_model.json): the quick design's fault runs,
    # with the protocol design's long healthy cycles (300-400 flights: every season at each
    # base), flown as a fleet in service and on the test station flies them: recordings of
    # 60 s (the demo's), 120 s (the protocol's) and 300 s, the station's conditions in
    # blocks of 40 flights. Its verification: 10 unseen aircraft, 300 healthy flights each.
    "shipped": {
        "design": ScaleConfig(duration_s=60.0, healthy_patterns=10, healthy_flights=(300, 400),
                              patterns_per_mode=6, render_every=21, apriori_flights=6,
                              apriori_onset=2, span_flights=ENVELOPE_FLIGHTS, span_draw="log",
                              recordings_s=(60.0, 60.0, 60.0, 120.0, 300.0),
                              condition_blocks=40),
        "verification": ScaleConfig(duration_s=60.0, healthy_patterns=10, healthy_flights=300,
                                    patterns_per_mode=3, render_every=21, apriori_flights=6,
                                    apriori_onset=2),
    },
    # The same protocol reduced for CI: every flight, a few patterns per mode, short
    # recordings and fast faults (a regression test of the machinery, not a figure).
    "ci": {
        "design": ScaleConfig(duration_s=30.0, healthy_patterns=10, healthy_flights=6,
                              patterns_per_mode=2, render_every=1, apriori_flights=4,
                              apriori_onset=2, span_flights=(15.0, 30.0)),
        "verification": ScaleConfig(duration_s=30.0, healthy_patterns=10, healthy_flights=6,
                                    patterns_per_mode=2, render_every=1, apriori_flights=4,
                                    apriori_onset=2, span_flights=(15.0, 30.0)),
        "concurrent": ScaleConfig(duration_s=30.0, healthy_patterns=0, healthy_flights=0,
                                  patterns_per_mode=2, render_every=1, apriori_flights=0,
                                  apriori_onset=0, lead_flights=2, span_flights=(8.0, 14.0)),
    },
}


#: the most fault patterns per mode a campaign plans (``--patterns-per-mode``): 99 keeps the
#: patterns' two-digit ids
MAX_PATTERNS_PER_MODE = 99

#: the longest step-fault (SE, BDO) pattern a campaign flies (``--step-flights``): a step
#: fault stays until its unit is replaced, and how many flights it takes to be found at the
#: demo's 60 s recordings is measured on patterns of tens of flights
MAX_STEP_FLIGHTS = 400


def kind_config(scale: str, kind: str) -> ScaleConfig:
    """The scale's campaign of ``kind``; a scale without one is refused, naming those with."""
    if scale not in SCALES:
        raise ValueError(f"scale must be one of {sorted(SCALES)}")
    if kind not in SCALES[scale]:
        raise ValueError(f"the {scale} scale has no {kind} campaign; scales with one: "
                         f"{sorted(s for s, kinds in SCALES.items() if kind in kinds)}")
    return SCALES[scale][kind]


def scale_config(scale: str, kind: str, render_every: int | None,
                 span_flights: tuple[float, float] | None,
                 span_draw: str | None = None,
                 recordings_s: Iterable[float] | None = None,
                 patterns_per_mode: int | None = None,
                 step_flights: int | None = None) -> ScaleConfig:
    cfg = kind_config(scale, kind)
    if step_flights is not None:
        if isinstance(step_flights, bool) or not isinstance(step_flights, int) \
                or not cfg.apriori_onset < step_flights <= MAX_STEP_FLIGHTS:
            raise ValueError(f"step-fault patterns must be an int of {cfg.apriori_onset + 1}.."
                             f"{MAX_STEP_FLIGHTS} flights (onset at flight "
                             f"{cfg.apriori_onset}), got {step_flights!r}")
        cfg = replace(cfg, apriori_flights=step_flights)
    if patterns_per_mode is not None:
        if isinstance(patterns_per_mode, bool) or not isinstance(patterns_per_mode, int) \
                or not 1 <= patterns_per_mode <= MAX_PATTERNS_PER_MODE:
            raise ValueError(f"patterns per mode must be an int in 1..{MAX_PATTERNS_PER_MODE}, "
                             f"got {patterns_per_mode!r}")
        cfg = replace(cfg, patterns_per_mode=patterns_per_mode)
    if recordings_s is not None:
        lengths = tuple(float(v) for v in recordings_s)
        if not lengths or not all(math.isfinite(v) and 10.0 <= v <= 600.0 for v in lengths):
            raise ValueError(f"recording lengths must lie in 10..600 s, got {lengths}")
        cfg = replace(cfg, recordings_s=lengths)
    if span_draw is not None:
        if span_draw not in SPAN_DRAWS:
            raise ValueError(f"span_draw must be one of {SPAN_DRAWS}, got {span_draw!r}")
        cfg = replace(cfg, span_draw=span_draw)
    if render_every is not None:
        if isinstance(render_every, bool) or not isinstance(render_every, int) \
                or render_every < 1 or render_every % 2 == 0:
            raise ValueError("render_every must be a positive odd int: the winglet's active "
                             "drive alternates by flight, so an even step would render a "
                             "faulty winglet drive in one role only")
        cfg = replace(cfg, render_every=render_every)
    if span_flights is not None:
        lo, hi = (float(v) for v in span_flights)
        if not (math.isfinite(lo) and math.isfinite(hi) and 1.0 <= lo <= hi <= _MAX_SPAN):
            raise ValueError(f"span range must satisfy 1 <= low <= high <= {_MAX_SPAN:g} "
                             f"flights, got {lo:g}..{hi:g}")
        cfg = replace(cfg, span_flights=(lo, hi))
    return cfg
