"""One flight of the simulated half-wing: conditions, 12 kHz simulation, flight log, summary.

Random draws, in this order, all from the ``rng`` passed in (seeded per aircraft and flight):
block hours, ground temperature, eq. (1) warp, gust sequence, sensor-noise seeds of the kernel.
:func:`estimate_summary` makes the same first draws, so an estimated summary (used for flights of
a fault-to-failure run that are not rendered) sees the same conditions as a simulated one would.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from datetime import datetime, timedelta, timezone

import numpy as np
from scipy.signal import lfilter

from server.flightlog import NOMINAL_SAMPLE_RATE_HZ, FlightLog, FlightMetadata
from server.vocabulary import POSITIONS

from .conditions import NO_CONDITIONS, Conditions
from .faults import ActuatorSummary, Faults, FlightSummary, as_faults, merged_entries
from .fleet import (
    DEFAULT_WINGLET_MODE,
    SURFACE_OF,
    WINGLET,
    WINGTIP,
    Aircraft,
    WingletMode,
    active_channels,
    draw_ground_temperature,
)
from .kernel import MAX_LANES, N_ACC, N_DBG, N_SIG, A, simulate
from .params import OUT_HZ, EmaParams, P, pack_ema, pack_surface
from .scenario import (
    CRUISE_TEMP_C,
    REFERENCE_DURATION_S,
    Scenario,
    Warp,
    build_scenario,
    draw_warp,
)

__all__ = [
    "EPOCH",
    "days_of_year",
    "FlightConditions",
    "SimResult",
    "draw_conditions",
    "imposed_conditions",
    "run_scenario",
    "run_kernel",
    "run_kernels",
    "kernel_inputs",
    "KernelInputs",
    "FlightSpec",
    "LANES",
    "simulate_flight",
    "simulate_flights",
    "estimate_summary",
    "flight_start",
    "reference_summary",
]

EPOCH = datetime(2024, 1, 1, 6, 0, tzinfo=timezone.utc)
SOURCE = "sim_worker RT model v1"
_SURFACES = (WINGLET, WINGTIP)
_X_LSB_M = 2.0**-20  # m, recorder resolution of the command channel
_T_LSB_C = 2.0**-6  # degC, recorder resolution of the ambient temperature
_SURF_LSB_RAD = 2.0**-18  # rad, recorder resolution of the surface deflections
_SIGNALS = ("ia", "ib", "ic", "va", "vb", "vc", "theta", "x")


def flight_start(flight_index: int, *, epoch: datetime = EPOCH, day_offset: float = 0.0
                 ) -> datetime:
    """Take-off time of flight ``flight_index``: two flights a day from ``epoch + day_offset``."""
    return epoch + timedelta(days=day_offset + 0.5 * flight_index)


def days_of_year(flight_indices: np.ndarray) -> np.ndarray:
    """Day of the year [days since 1 January 00:00] of each flight's take-off
    (:func:`flight_start`)."""
    starts = [flight_start(int(n)) for n in flight_indices]
    return np.array([(t - t.replace(month=1, day=1, hour=0, minute=0)).total_seconds() / 86400
                     for t in starts])


@dataclass(frozen=True)
class FlightConditions:
    started_at: datetime
    block_hours: float  # h
    ground_temp_c: float  # degC
    warp: Warp


@dataclass(frozen=True)
class SimResult:
    """Raw kernel outputs of one run (sensor signals and true states at 800 Hz)."""

    scenario: Scenario
    signals: np.ndarray  # (n, 3, 8) measured ia ib ic [A] va vb vc [V] theta [rad] x [m]
    surfaces: np.ndarray  # (n, 2) rad
    truth: np.ndarray  # (n, 3, N_DBG) true states, see kernel.D
    acc: np.ndarray  # (3, N_ACC) accumulators, see kernel.A
    params: np.ndarray  # (3, N_PAR) the kernel parameter rows used


def draw_conditions(aircraft: Aircraft, flight_index: int, rng: np.random.Generator, *,
                    started_at: datetime | None = None) -> FlightConditions:
    start = started_at if started_at is not None else flight_start(flight_index)
    block_hours = float(np.clip(rng.normal(1.4, 0.4), 0.6, 3.0))
    ground = draw_ground_temperature(aircraft.base, start.month, rng)
    return FlightConditions(started_at=start, block_hours=round(block_hours, 3),
                            ground_temp_c=ground, warp=draw_warp(rng))


def imposed_conditions(aircraft: Aircraft, flight_index: int, rng: np.random.Generator,
                       imposed: Conditions, *, started_at: datetime | None = None
                       ) -> FlightConditions:
    """The flight's drawn conditions under the test station's ``imposed`` ones: the same draws
    (from the imposed base's climate), then the ambient offset and the eq. (1) changes."""
    at = aircraft if imposed.base is None else replace(aircraft, base=imposed.base)
    cond = draw_conditions(at, flight_index, rng, started_at=started_at)
    if imposed == NO_CONDITIONS:
        return cond
    return replace(cond, ground_temp_c=cond.ground_temp_c + imposed.ambient_offset_k,
                   warp=imposed.warp(cond.warp))


@dataclass(frozen=True)
class KernelInputs:
    """One flight's kernel inputs: its parameter rows, its surfaces' and its sensor-noise seeds
    (the scenario holds the commands, loads and ambient)."""

    scenario: Scenario
    params: np.ndarray  # (3, N_PAR) one row per position, see params.P
    surfaces: np.ndarray  # (2, N_SURF_PAR)
    seeds: np.ndarray  # (3,) uint64, non-zero


def kernel_inputs(aircraft: Aircraft, fault: Faults, scenario: Scenario,
                  rng: np.random.Generator, *, t0_winding_c: float | None = None,
                  active: tuple[str, ...] = POSITIONS) -> KernelInputs:
    """Pack ``scenario`` with ``fault`` (one fault, or a tuple of concurrent ones: each on its
    position, two on one actuator both applied, :func:`~.faults.merged_entries`) for the
    kernel, and draw the sensor-noise seeds from ``rng``; the drives not in ``active`` are in
    standby (each surface needs an active one)."""
    t0 = float(scenario.t_amb[0] + 3.0) if t0_winding_c is None else t0_winding_c
    faults = as_faults(fault)  # checked once for every position
    for s in set(SURFACE_OF.values()):
        if not any(SURFACE_OF[p] == s for p in active):
            raise ValueError(f"active={active!r} leaves surface {_SURFACES[s].name} undriven")
    par = np.stack([
        pack_ema(aircraft.ema[pos], aircraft.nominal, surface=SURFACE_OF[pos],
                 arm_m=_SURFACES[SURFACE_OF[pos]].arm_m, offsets=aircraft.offsets[pos],
                 faults=merged_entries(faults, pos), t0_winding_c=t0,
                 standby=pos not in active)
        for pos in POSITIONS
    ])
    spar = np.stack([pack_surface(s) for s in _SURFACES])
    seeds = rng.integers(1, 2**63 - 1, size=len(POSITIONS), dtype=np.uint64)
    return KernelInputs(scenario=scenario, params=par, surfaces=spar, seeds=seeds)


def run_scenario(aircraft: Aircraft, fault: Faults, scenario: Scenario,
                 rng: np.random.Generator, *, t0_winding_c: float | None = None,
                 active: tuple[str, ...] = POSITIONS) -> SimResult:
    """Simulate ``scenario`` at 12 kHz with ``fault`` (one, or a tuple of concurrent ones) on
    its position (kernel call); the drives not in ``active`` are in standby (each surface
    needs an active one)."""
    return run_kernel(kernel_inputs(aircraft, fault, scenario, rng, t0_winding_c=t0_winding_c,
                                    active=active))


def run_kernel(inp: KernelInputs) -> SimResult:
    """One flight through the kernel: a batch of one."""
    return run_kernels([inp])[0]


def run_kernels(inputs: Sequence[KernelInputs], *, truth: bool = True) -> list[SimResult]:
    """Flights through the kernel in one call, one lane each (:func:`kernel.simulate`, at most
    ``kernel.MAX_LANES``); each result is the flight's alone, whatever flies beside it, and
    views the batch's arrays. Without ``truth`` the true states are not recorded (their
    ``truth`` has no samples). Every flight's positions must be on the same surfaces (they
    are: :data:`fleet.SURFACE_OF`)."""
    if not inputs:
        return []
    if len(inputs) > MAX_LANES:
        raise ValueError(f"{len(inputs)} flights in one kernel call: at most {MAX_LANES}")
    par = np.stack([inp.params for inp in inputs], axis=-1)
    if np.any(par[:, P.SURF, :] != par[:, P.SURF, :1]):
        raise ValueError("every flight of a batch needs its EMAs on the same surfaces")
    lengths = np.array([inp.scenario.t.shape[0] for inp in inputs], dtype=np.int64)
    if np.any(lengths < 1):
        raise ValueError("a flight needs at least one output sample")
    n = int(lengths.max())
    n_ema, n_surf, lanes = par.shape[0], inputs[0].surfaces.shape[0], len(inputs)
    # lane-major outputs, each sample written by the kernel (a lane runs on to n)
    out = np.empty((lanes, n, n_ema, N_SIG))
    surf = np.empty((lanes, n, n_surf))
    dbg = np.empty((lanes, n if truth else 0, n_ema, N_DBG))
    acc = np.empty((lanes, n_ema, N_ACC))
    simulate(par, np.stack([inp.surfaces for inp in inputs], axis=-1),
             _lanes([inp.scenario.x_cmd for inp in inputs], n),
             _lanes([inp.scenario.f_ext for inp in inputs], n),
             _lanes([inp.scenario.t_amb for inp in inputs], n),
             np.stack([inp.seeds for inp in inputs], axis=-1), lengths, out, surf, dbg, acc)
    return [SimResult(scenario=inp.scenario, signals=out[ln, :m], surfaces=surf[ln, :m],
                      truth=dbg[ln, :m], acc=acc[ln], params=inp.params)
            for ln, (inp, m) in enumerate(zip(inputs, lengths, strict=True))]


def _lanes(series: list[np.ndarray], n: int) -> np.ndarray:
    """Per-flight input series (samples first) stacked on a last lane axis, each run on to
    ``n`` samples by repeating its last (what the kernel's lane does after the flight's end)."""
    out = np.empty((n, *series[0].shape[1:], len(series)))
    for ln, a in enumerate(series):
        out[:a.shape[0], ..., ln] = a
        out[a.shape[0]:, ..., ln] = a[-1]
    return out


def _q32(v: np.ndarray, lsb: float) -> np.ndarray:
    return (np.round(v / lsb) * lsb).astype(np.float32)


def _summary_from_acc(acc: np.ndarray, cond: FlightConditions, duration_s: float
                      ) -> FlightSummary:
    acts = {}
    for k, pos in enumerate(POSITIONS):
        a = acc[k]
        n = max(a[A.N], 1.0)
        acts[pos] = ActuatorSummary(
            winding_mean_c=float(a[A.TW_SUM] / n), winding_max_c=float(a[A.TW_MAX]),
            current_rms_a=float(np.sqrt(a[A.I2_SUM] / n)),
            load_rms_n=float(np.sqrt(a[A.F2_SUM] / n)),
            work_screw_n_m=float(a[A.WORK_SCREW]), work_rod_end_n_m=float(a[A.WORK_ROD]),
            travel_m=float(a[A.TRAVEL]))
    return FlightSummary(actuators=acts, block_hours=cond.block_hours,
                         ground_temp_c=cond.ground_temp_c, duration_s=duration_s, measured=True)


def simulate_flight(
    aircraft: Aircraft,
    fault: Faults,
    flight_index: int,
    rng: np.random.Generator,
    *,
    flight_id: str | None = None,
    started_at: datetime | None = None,
    duration_s: float = REFERENCE_DURATION_S,
    winglet_mode: WingletMode = DEFAULT_WINGLET_MODE,
    conditions: Conditions = NO_CONDITIONS,
) -> tuple[FlightLog, FlightSummary]:
    """Simulate one flight with ``fault`` (one, or a tuple of concurrent ones) and return its
    download (format v1) and what the actuators did;
    under active-standby the log's metadata names the flight's active channels. The test
    station's ``conditions`` move its physics (:mod:`.conditions`), not its metadata. A batch
    of one of :func:`simulate_flights`."""
    return simulate_flights([FlightSpec(
        aircraft, fault, flight_index, rng, flight_id=flight_id, started_at=started_at,
        duration_s=duration_s, winglet_mode=winglet_mode, conditions=conditions)])[0]


@dataclass(frozen=True)
class FlightSpec:
    """One flight to simulate: the arguments of :func:`simulate_flight`. ``rng`` is the
    flight's own (seeded per aircraft and flight): its draws are made in a lone flight's
    order, whatever flies beside it. ``fault``: one fault (``healthy()`` for none) or a
    tuple of concurrent ones."""

    aircraft: Aircraft
    fault: Faults
    flight_index: int
    rng: np.random.Generator
    flight_id: str | None = None
    started_at: datetime | None = None
    duration_s: float = REFERENCE_DURATION_S
    winglet_mode: WingletMode = DEFAULT_WINGLET_MODE
    conditions: Conditions = NO_CONDITIONS


#: flights per kernel call by default: 8 lanes fill the vector registers once (AVX-512, 8
#: float64); 16 are about an eighth faster per flight and hold twice the memory
#: (docs/BENCHMARKS.md)
LANES = 8
#: flights prepared at once per kernel call's worth, to group them by length (a kernel call
#: runs to its longest flight) while holding only a few batches' scenarios
_WINDOW_BATCHES = 4


@dataclass(frozen=True)
class _Prepared:
    spec: FlightSpec
    cond: FlightConditions
    active: tuple[str, ...]
    inputs: KernelInputs


def simulate_flights(specs: Sequence[FlightSpec], *, lanes: int = LANES
                     ) -> list[tuple[FlightLog, FlightSummary]]:
    """Simulate ``specs`` several at once, ``lanes`` flights per kernel call (each flight a
    lane, flights of similar length together), and return each flight's download and summary,
    in the order of ``specs``: each equals what :func:`simulate_flight` gives for its spec
    alone, bit for bit (tests/sim/test_kernel_lanes.py). The flights are independent: a
    campaign batches flights of different aircraft or patterns, not the next flight of an
    aircraft whose fault advances on this one's summary."""
    if not 1 <= lanes <= MAX_LANES:
        raise ValueError(f"lanes must be in [1, {MAX_LANES}], got {lanes}")
    if len({id(spec.rng) for spec in specs}) != len(specs):
        raise ValueError("each flight needs its own random generator")
    results: list[tuple[FlightLog, FlightSummary] | None] = [None] * len(specs)
    window = lanes * _WINDOW_BATCHES
    for start in range(0, len(specs), window):
        prepared = {i: _prepare(specs[i]) for i in range(start, min(start + window, len(specs)))}
        by_length = sorted(prepared, key=lambda i: prepared[i].inputs.scenario.t.shape[0])
        for b in range(0, len(by_length), lanes):
            batch = by_length[b:b + lanes]
            sims = run_kernels([prepared[i].inputs for i in batch], truth=False)
            for i, sim in zip(batch, sims, strict=True):
                results[i] = _flight_outputs(prepared[i], sim)
    return [r for r in results if r is not None]


def _prepare(spec: FlightSpec) -> _Prepared:
    """The flight's draws, in a lone flight's order: conditions, scenario, sensor seeds."""
    cond = imposed_conditions(spec.aircraft, spec.flight_index, spec.rng, spec.conditions,
                              started_at=spec.started_at)
    scenario = build_scenario(cond.warp, cond.ground_temp_c, spec.rng,
                              duration_s=spec.duration_s,
                              cruise_temp_c=CRUISE_TEMP_C + spec.conditions.ambient_offset_k)
    active = active_channels(spec.winglet_mode, spec.flight_index)
    return _Prepared(spec, cond, active, kernel_inputs(spec.aircraft, spec.fault, scenario,
                                                       spec.rng, active=active))


def _flight_outputs(p: _Prepared, res: SimResult) -> tuple[FlightLog, FlightSummary]:
    """The flight's download and summary from its kernel outputs."""
    spec, scenario = p.spec, p.inputs.scenario
    channels: dict[str, np.ndarray] = {"t": scenario.t.astype(np.float64)}
    # one cast into (EMA, signal, sample) order: each channel a contiguous row, not a strided
    # copy of its own
    signals = np.ascontiguousarray(res.signals.transpose(1, 2, 0), dtype=np.float32)
    for k, pos in enumerate(POSITIONS):
        for i, sig in enumerate(_SIGNALS):
            channels[f"{pos}.{sig}"] = signals[k, i]
    for k, pos in enumerate(POSITIONS):
        channels[f"{pos}.x_cmd"] = _q32(scenario.x_cmd[:, k], _X_LSB_M)
    channels["T_amb"] = _q32(scenario.t_amb, _T_LSB_C)
    channels["surf_WL"] = _q32(res.surfaces[:, 0], _SURF_LSB_RAD)
    channels["surf_WT"] = _q32(res.surfaces[:, 1], _SURF_LSB_RAD)
    aircraft = spec.aircraft
    meta = FlightMetadata(
        aircraft=aircraft.tail,
        flight=spec.flight_id or f"{aircraft.tail}-F{spec.flight_index:05d}",
        started_at=p.cond.started_at,
        block_hours=p.cond.block_hours,
        sample_rate_hz=NOMINAL_SAMPLE_RATE_HZ,
        actuator_serials=dict(aircraft.serials),
        source=SOURCE,
        active_channels=None if p.active == POSITIONS else p.active,
    )
    duration = float(scenario.t[-1]) if scenario.t.size else 0.0
    return (FlightLog(metadata=meta, channels=channels),
            _summary_from_acc(res.acc, p.cond, duration))


def estimate_summary(aircraft: Aircraft, flight_index: int, rng: np.random.Generator, *,
                     started_at: datetime | None = None,
                     duration_s: float = REFERENCE_DURATION_S,
                     conditions: FlightConditions | None = None,
                     winglet_mode: WingletMode = DEFAULT_WINGLET_MODE) -> FlightSummary:
    """Quasi-static estimate of :class:`FlightSummary` from the scenario alone (no 12 kHz run).

    Travel and sliding work from the command; an active drive's link force from the hinge
    load it carries (its surface's aerodynamic load and hinge damping shared among the
    surface's active drives, plus the standby's drag), a standby's from its damping and drag
    (:func:`_standby_force`); current from force x lead / (efficiency x torque constant), or
    a standby's damping current; winding temperature from the same first-order thermal model
    driven by ambient and copper losses. On the active-standby tab a drive carries what its role
    gives it, worn or not, so unrendered flights wear it as rendered ones do (within 8 %,
    bench/fast_path_agreement.py), and the estimate needs no fault. An active-active pair's
    estimate shares the load evenly and does not know that a worn drive hands its load to its
    partner: campaigns fly active-standby.
    """
    cond = conditions or draw_conditions(aircraft, flight_index, rng, started_at=started_at)
    sc = build_scenario(cond.warp, cond.ground_temp_c, rng, duration_s=duration_s)
    active = active_channels(winglet_mode, flight_index)
    acts = {}
    for k, pos in enumerate(POSITIONS):
        surface = SURFACE_OF[pos]
        x = sc.x_cmd[:, k]
        dx = np.abs(np.diff(x, prepend=x[0]))
        v = np.gradient(x) * OUT_HZ  # m/s, the command's rate
        standby = [q for q in POSITIONS if SURFACE_OF[q] == surface and q not in active]
        if pos in active:
            n_active = sum(1 for q in active if SURFACE_OF[q] == surface)
            surf = _SURFACES[surface]
            # aerodynamic load and hinge damping (C_h w at the rod: C_h v / arm^2) of the surface
            hinge = (-sc.f_ext[:, surface] * surf.n_actuators
                     + surf.hinge_damping_nms * v / surf.arm_m**2) / n_active
            drag = sum(_standby_force(aircraft.ema[q], v)[0] for q in standby)
            f, i = _active_force(aircraft.ema[pos], hinge + np.sign(v) * drag)
            # a lone active link flexes with the load: the rod end slides with the surface
            # while the nut holds
            flex = _flex_sliding(aircraft.ema[pos], f) if standby else 0.0
        else:
            f, i = _standby_force(aircraft.ema[pos], v)
            flex = 0.0
        acts[pos] = _estimated_actuator(aircraft.ema[pos], sc, cond, f, i, dx, flex)
    return FlightSummary(actuators=acts, block_hours=cond.block_hours,
                         ground_temp_c=cond.ground_temp_c,
                         duration_s=float(sc.t[-1]) if sc.t.size else 0.0, measured=False)


def _active_force(p: EmaParams, link_n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """|Link force| [N] and q current [A] of a drive holding ``link_n`` (quasi-static)."""
    f = np.abs(link_n)
    kt = 1.5 * p.motor.pole_pairs * p.motor.psi_pm_wb
    return f, (f * p.screw.r_m_per_rad / p.screw.eta_direct + p.screw.coulomb_torque_nm) / kt


def _flex_sliding(p: EmaParams, f: np.ndarray) -> float:
    """Rod-end sliding work [N m] of the link's deflection under a varying force:
    sum |F| |dF| / k (screw and rod-end stiffness in series)."""
    k = 1.0 / (1.0 / p.screw.k_screw_n_per_m + 1.0 / p.screw.k_rod_end_n_per_m)
    return float(np.sum(f[1:] * np.abs(np.diff(f)))) / k


def _standby_force(p: EmaParams, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """|Link force| [N] and damping current [A] of a standby drive back-driven at rod speed
    ``v``: its shorted windings' torque ``b w``, ``b = 1.5 p^2 psi^2 / (R_s + R_d)``, plus the
    drag, through the back-driving efficiency; nothing while the rod is still."""
    m, s = p.motor, p.screw
    r = s.r_m_per_rad
    w = np.abs(v) / r
    r_total = m.r_s_ohm + p.inverter.damping_resistance_ohm
    b = 1.5 * m.pole_pairs**2 * m.psi_pm_wb**2 / r_total
    _, eta_b = s.efficiencies()
    f = np.where(w > 0.0, (b * w + s.coulomb_torque_nm) / (eta_b * r), 0.0)
    return f, m.pole_pairs * m.psi_pm_wb * w / r_total


def _estimated_actuator(p: EmaParams, sc: Scenario, cond: FlightConditions, f: np.ndarray,
                        i: np.ndarray, dx: np.ndarray, flex_n_m: float
                        ) -> ActuatorSummary:
    """Summary of one drive from its estimated force and current: the winding heated by
    its copper losses (a standby's damping resistors are outside the motor)."""
    r_hot = p.motor.r_s_ohm * (1.0 + p.motor.alpha_cu_per_k * (cond.ground_temp_c - 20.0))
    p_cu = 1.5 * r_hot * i**2
    rth, cth = p.thermal.r_th_k_per_w, p.thermal.c_th_j_per_k
    a = 1.0 - (1.0 / OUT_HZ) / (rth * cth)
    u = sc.t_amb + rth * p_cu
    t0 = float(sc.t_amb[0] + 3.0)
    tw, _ = lfilter([1.0 - a], [1.0, -a], u, zi=[a * t0])
    work = float(np.sum(f * dx))
    return ActuatorSummary(
        winding_mean_c=float(np.mean(tw)), winding_max_c=float(np.max(tw)),
        current_rms_a=float(np.sqrt(np.mean(i**2))), load_rms_n=float(np.sqrt(np.mean(f**2))),
        work_screw_n_m=work, work_rod_end_n_m=work + flex_n_m, travel_m=float(np.sum(dx)))


def reference_summary(aircraft: Aircraft, position: str, *, duration_s: float,
                      seed: int | tuple[int, ...],
                      winglet_mode: WingletMode = DEFAULT_WINGLET_MODE) -> ActuatorSummary:
    """Average of 24 estimated flights of the aircraft at its base, spread over a year: the
    expected conditions against which a progressive fault's rate is calibrated (so that its
    span holds on average, not only on one drawn flight); active-standby drives take each
    role on half of them, as in service."""
    key = (seed,) if isinstance(seed, int) else tuple(seed)
    n = 24
    sums = [estimate_summary(aircraft, i, np.random.default_rng([*key, 99, i]),
                             started_at=flight_start(i * 30), duration_s=duration_s,
                             winglet_mode=winglet_mode).actuators[position] for i in range(n)]
    return ActuatorSummary(**{k: float(np.mean([getattr(s, k) for s in sums]))
                              for k in ActuatorSummary.__dataclass_fields__})
