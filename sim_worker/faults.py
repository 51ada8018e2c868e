"""The seven fault modes: severity, failure threshold, physical entry point and progression law.

Severity units (per fault, on one actuator position):

============  =========================================  ============  ==========  ===========
mode          severity                                   threshold     onset       progression
============  =========================================  ============  ==========  ===========
``TTS``       fraction of phase-a turns shorted [-]      0.10          0.005       Arrhenius
``DMD``       irreversible PM flux loss h [-]             0.20          0.010       thermal
``SE``        relative static eccentricity [-]           0.50          drawn       a priori
``BDO``       leg-a upper MOSFET base drive open [-]     1.0           1.0         a priori
``MTEL``      loss of direct screw efficiency [-]        0.15          0.0075      grease life
``MTWEAR``    added ball-screw backlash [m]              0.3e-3        1.5e-5      Archard
``REWEAR``    added rod-end backlash [m]                 2.0e-3        1.0e-4      Archard
============  =========================================  ============  ==========  ===========

Progression per flight, on the normalised severity ``s_n = s / threshold``::

    s_n+ = s_n + rate * driver(summary) * (s_n + c_mode) * exp(N(0, 0.3^2) - 0.045)

``driver`` is the physics law measured from the flight: insulation life halves per +10 K of mean
winding temperature (TTS; Montsinger, IEC 60085 practice); magnet loss grows with temperature and
current loading (DMD); grease life halves per +15 K above 70 degC (MTEL; SKF relubrication rule);
Archard wear volume ``K F_N s / H`` grows with force times sliding distance on the screw (MTWEAR)
and on the rod end (REWEAR). Every driver is multiplied by the flight's block hours over 1.5 h.
``rate`` is drawn per pattern so that the expected fault-to-failure span at the base's average
conditions is ``U(170, 360)`` flights (accelerated ageing, as in the paper; verification
campaigns), or log-uniform over the test station's envelope of 30-1000 flights (design
campaigns, ``ENVELOPE_FLIGHTS``); actual spans spread further with season and usage. On the
active-standby winglet tab each drive carries what its role gives it, worn or not, so a worn
drive's wear is driven by the work it does in its role.

Concurrent faults. A flight may carry several faults (:data:`Faults`): on different actuators,
or of different modes on one actuator. Each mode enters the kernel's parameter row at its own
entries (:func:`fault_entries`: winding, magnets, air gap, inverter leg, screw friction, screw
play, rod-end play), so two faults on one actuator are both sets of entries applied at once
(:func:`merged_entries`); the physics couples them through the signals (a greased-up screw
loads a worn screw harder, a hotter winding ages a shorted one faster), not through the entries.
Two faults of the same mode on one position have no meaning (one severity per mode) and are
refused. Each fault progresses by its own law and rate from the same flight summary
(:func:`advance_fault`, one call per fault, each with its own random stream).

Failure: when any fault on an actuator reaches its threshold the actuator has failed; it is
replaced after that flight (its failure flight, flown with every fault it carries), and every
fault on it ends there. A second fault on that actuator never reached its own threshold: it is
censored, its failure flight unknown (its true RUL ``None``). Faults on other actuators fly on.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from server.vocabulary import ABRUPT, FAULT_MODES, POSITIONS, PROGRESSIVE

__all__ = [
    "MODES",
    "PROGRESSIVE",
    "A_PRIORI",
    "THRESHOLDS",
    "ENVELOPE_FLIGHTS",
    "SPAN_DRAWS",
    "SPAN_FLIGHTS",
    "ActuatorSummary",
    "FlightSummary",
    "FaultState",
    "healthy",
    "fault_at",
    "new_fault",
    "advance_fault",
    "fault_entries",
    "merged_entries",
    "as_faults",
    "Faults",
    "draw_span",
    "expected_span",
    "driver",
    "reference_driver",
    "life_integral",
    "life_to_go",
]

MODES: tuple[str, ...] = FAULT_MODES
A_PRIORI: tuple[str, ...] = ABRUPT  # imposed at a constant severity, no progression
THRESHOLDS: dict[str, float] = {"TTS": 0.10, "DMD": 0.20, "SE": 0.5, "BDO": 1.0, "MTEL": 0.15,
                                "MTWEAR": 0.3e-3, "REWEAR": 2.0e-3}
_ONSET_NORM = 0.05  # onset severity / threshold of the progressive modes
_GROWTH_C = {"TTS": 0.05, "DMD": 0.3, "MTEL": 0.1, "MTWEAR": 2.0, "REWEAR": 0.8}
#: default range of expected fault-to-failure spans [flights] (accelerated ageing, as in the paper)
SPAN_FLIGHTS = (170.0, 360.0)
#: how a span is drawn from its range: uniformly, or log-uniformly (spans are scales: a
#: design over 30-1000 flights needs as many fast runs as slow ones)
SPAN_DRAWS = ("uniform", "log")
#: the test station's envelope of times to failure a design campaign spans, log-uniformly
#: [flights]: from a fault that fails within a month of two flights a day to one that takes
#: over a year (a request outside it is warned of as an extrapolation)
ENVELOPE_FLIGHTS = (30.0, 1000.0)
_PROCESS_SD = 0.3
_BLOCK_HOURS_REF = 1.5
_WORK_REF_N_M = 300.0  # N m, screw sliding work of a typical recorded flight
TTS_RF_OHM = 0.1  # Ohm, resistance of the insulation breakdown path between shorted turns
TTS_LEAK_S_AT_FAILURE = 0.05  # S, winding-to-frame leakage conductance at the threshold [est]
SE_FLUX_PER_ECC = 0.5  # relative flux modulation per unit relative eccentricity [est]


@dataclass(frozen=True)
class ActuatorSummary:
    """What one actuator did in one flight (measured from the simulation or estimated)."""

    winding_mean_c: float  # degC
    winding_max_c: float  # degC
    current_rms_a: float  # A, sqrt(mean(i_d^2 + i_q^2)) (peak-value d-q)
    load_rms_n: float  # N, link force
    work_screw_n_m: float  # N m, integral |F| |v_nut| dt
    work_rod_end_n_m: float  # N m, integral |F| |v_attachment| dt
    travel_m: float  # m, integral |v_nut| dt


@dataclass(frozen=True)
class FlightSummary:
    """One flight: per-position actuator summaries plus flight conditions."""

    actuators: dict[str, ActuatorSummary]
    block_hours: float  # h
    ground_temp_c: float  # degC
    duration_s: float  # s, recorded
    measured: bool  # True when from the 12 kHz simulation, False when estimated


@dataclass(frozen=True)
class FaultState:
    """One actuator fault (``mode == "healthy"`` for none)."""

    mode: str
    position: str | None
    severity: float
    threshold: float | None
    rate: float = 0.0  # 1/flight, progression rate constant (progressive modes)
    phase_rad: float = 0.0  # SE: angle of the narrowest air gap

    @property
    def severity_norm(self) -> float:
        return 0.0 if not self.threshold else self.severity / self.threshold

    @property
    def failed(self) -> bool:
        return self.mode in PROGRESSIVE and self.severity >= (self.threshold or math.inf)


#: what a flight carries: one fault (``healthy()`` for none), or several at once
Faults = FaultState | tuple[FaultState, ...]


def healthy() -> FaultState:
    return FaultState(mode="healthy", position=None, severity=0.0, threshold=None)


def as_faults(faults: Faults) -> tuple[FaultState, ...]:
    """The faults a flight carries, as a tuple (the healthy placeholder dropped), checked: each
    of a known mode on a position of the half-wing, no mode twice on one position."""
    if isinstance(faults, FaultState):
        faults = (faults,)
    out = tuple(f for f in faults if f.mode != "healthy")
    seen: set[tuple[str, str]] = set()
    for f in out:
        if f.mode not in MODES:
            raise ValueError(f"unknown fault mode {f.mode!r}")
        if f.position not in POSITIONS:
            raise ValueError(f"a {f.mode} fault needs a position among {POSITIONS}, "
                             f"got {f.position!r}")
        if (f.mode, f.position) in seen:
            raise ValueError(f"two {f.mode} faults on {f.position}: one actuator has one "
                             f"severity per mode")
        seen.add((f.mode, f.position))
    return out


def driver(mode: str, s: ActuatorSummary, block_hours: float) -> float:
    """Physics driver of one flight for ``mode`` (dimensionless, about 1 at mild conditions)."""
    bh = block_hours / _BLOCK_HOURS_REF
    if mode == "TTS":  # Montsinger / Arrhenius: life halves per +10 K
        return bh * 2.0 ** ((s.winding_mean_c - 40.0) / 10.0)
    if mode == "DMD":  # hot magnet under armature loading
        loading = 1.0 + (s.current_rms_a / 6.0) ** 2
        return bh * math.exp((s.winding_mean_c - 40.0) / 25.0) * loading
    if mode == "MTEL":  # SKF: grease life halves per +15 K above 70 degC
        return bh * 2.0 ** ((s.winding_mean_c - 70.0) / 15.0)
    if mode == "MTWEAR":  # Archard: K F_N s / H
        return bh * s.work_screw_n_m / _WORK_REF_N_M
    if mode == "REWEAR":
        return bh * s.work_rod_end_n_m / _WORK_REF_N_M
    return 0.0


def reference_driver(mode: str, reference: ActuatorSummary) -> float:
    """The driver of the reference flight (the base's expected conditions) at the reference
    block hours: what a progressive fault's rate is calibrated against."""
    return max(driver(mode, reference, _BLOCK_HOURS_REF), 1e-9)


def life_integral(onset_norm: float, growth_c: float) -> float:
    """``int_onset^1 ds / (s + c) = ln((1 + c) / (onset + c))``: flights to failure times rate
    times driver. The progression ``ds/dn = rate d (s + c)`` (:func:`advance_fault`, with the
    driver ``d`` of the estimated reference flight) reaches ``s = 1`` after this integral /
    (rate d) flights."""
    return math.log((1.0 + growth_c) / (onset_norm + growth_c))


def life_to_go(state: FaultState) -> float:
    """:func:`life_integral` from the fault's severity now: flights to failure times rate times
    the mean driver."""
    if state.mode not in PROGRESSIVE or state.position is None:
        raise ValueError(f"{state.mode} has no progression")
    return life_integral(min(state.severity_norm, 1.0), _GROWTH_C[state.mode])


def fault_at(mode: str, position: str | None, severity_norm: float, *,
             phase_rad: float = 0.0) -> FaultState:
    """A fault held at ``severity_norm`` of its threshold (``"healthy"``: none), no
    progression: what a regression case or a feature canary flies."""
    if mode == "healthy":
        return healthy()
    thr = THRESHOLDS[mode]
    return FaultState(mode, position, severity_norm * thr, thr, phase_rad=phase_rad)


def new_fault(mode: str, position: str, rng: np.random.Generator, *,
              reference: ActuatorSummary | None = None, span_flights: float | None = None,
              span_range: tuple[float, float] = SPAN_FLIGHTS, span_draw: str = "uniform",
              severity_norm: float | None = None) -> FaultState:
    """A fault at onset. Progressive modes draw the rate so that, at the ``reference`` flight
    (the base's average conditions, estimated), failure comes after ``U(*span_range)`` flights
    (default U(170, 360); ``span_draw="log"``: log-uniform over the range), or after
    ``span_flights`` when a test-station operator sets it.
    ``severity_norm`` imposes the severity of an a priori fault (SE) as a fraction of its
    threshold."""
    if mode not in MODES:
        raise ValueError(f"unknown fault mode {mode!r}")
    thr = THRESHOLDS[mode]
    if mode == "SE":
        drawn = float(rng.uniform(0.12, 0.35))
        return FaultState(mode, position, drawn if severity_norm is None else severity_norm * thr,
                          thr, phase_rad=float(rng.uniform(0.0, 2.0 * math.pi)))
    if mode == "BDO":
        return FaultState(mode, position, 1.0, thr)
    if reference is None:
        raise ValueError("progressive modes need a reference flight summary to set the rate")
    span = draw_span(rng, span_range, span_draw) if span_flights is None \
        else float(span_flights)
    rate = life_integral(_ONSET_NORM, _GROWTH_C[mode]) / (span * reference_driver(mode, reference))
    return FaultState(mode, position, _ONSET_NORM * thr, thr, rate=rate)


def draw_span(rng: np.random.Generator, span_range: tuple[float, float], draw: str) -> float:
    """One expected span from its range; one uniform draw either way."""
    if draw == "uniform":
        return float(rng.uniform(*span_range))
    if draw == "log":
        lo, hi = span_range
        return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))
    raise ValueError(f"span_draw must be one of {SPAN_DRAWS}, got {draw!r}")


def expected_span(state: FaultState, reference: ActuatorSummary) -> float:
    """Flights a progressive fault takes from its severity now to failure at the ``reference``
    flight's conditions (what its rate was drawn for, :func:`new_fault`)."""
    if state.rate <= 0.0:
        raise ValueError(f"{state.mode} on {state.position} does not progress")
    return life_to_go(state) / (state.rate * reference_driver(state.mode, reference))


def advance_fault(state: FaultState, summary: FlightSummary, rng: np.random.Generator
                  ) -> FaultState:
    """Severity after one flight, by the mode's law driven by what the flight did."""
    if state.mode not in PROGRESSIVE or state.position is None or state.threshold is None:
        return state
    s = summary.actuators[state.position]
    sn = state.severity_norm
    noise = math.exp(_PROCESS_SD * float(rng.standard_normal()) - 0.5 * _PROCESS_SD**2)
    dsn = state.rate * driver(state.mode, s, summary.block_hours) * (sn + _GROWTH_C[state.mode])
    return replace(state, severity=(sn + dsn * noise) * state.threshold)


def fault_entries(state: FaultState, position: str) -> dict[str, float]:
    """Model entries (see params.pack_ema) for the actuator at ``position``."""
    if state.position != position or state.mode == "healthy":
        return {}
    s = state.severity
    if state.mode == "TTS":
        return {"tts_sigma": s, "tts_rf_ohm": TTS_RF_OHM,
                "tts_g_s": TTS_LEAK_S_AT_FAILURE * s / THRESHOLDS["TTS"]}
    if state.mode == "DMD":
        return {"dmd_h": s}
    if state.mode == "SE":
        return {"se_eps": SE_FLUX_PER_ECC * s, "se_phi": state.phase_rad}
    if state.mode == "BDO":
        return {"bdo_leg": 0.0, "bdo_upper": 1.0}
    if state.mode == "MTEL":
        # grease aging: screw friction angle up (efficiency down) and seal/bearing drag up
        return {"mtel_deta": s, "mtel_drag": 2.0 * s / THRESHOLDS["MTEL"]}
    if state.mode == "MTWEAR":
        return {"screw_backlash_m": s}
    if state.mode == "REWEAR":
        return {"rod_end_backlash_m": s}
    raise ValueError(state.mode)


def merged_entries(faults: Faults, position: str) -> dict[str, float]:
    """Model entries of every fault on the actuator at ``position``: each mode's own entries
    (:func:`fault_entries`), which no two modes share; the faults are checked as
    :func:`as_faults` does."""
    merged: dict[str, float] = {}
    for state in as_faults(faults):
        entries = fault_entries(state, position)
        if merged.keys() & entries.keys():  # a new mode writing another's entries: a bug
            raise ValueError(f"{state.mode} shares parameter entries with another mode on "
                             f"{position}: {sorted(merged.keys() & entries.keys())}")
        merged |= entries
    return merged
