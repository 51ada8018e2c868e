"""Signal-quality figures of a flight's channels: each figure measures what it says on
synthetic channels with a known noise, step, offset, frozen span or rail, and on simulated
flights a sensor flown noisier is the one whose floor rises."""

from __future__ import annotations

import numpy as np
import pytest

from server.flightlog import FlightLog
from server.phm.features import MotorConstants
from server.phm.signal_quality import (
    FLOOR_CHANNELS,
    QualityConfig,
    channel_quality,
    flight_quality,
    still_samples,
)
from server.phm.signal_quality_loops import channel_counts
from server.vocabulary import POSITIONS, SIGNALS
from sim_worker.campaign import fleet_for
from sim_worker.faults import healthy
from sim_worker.flight import simulate_flight

FS = 800.0
RADIUS = MotorConstants().screw_radius_m
POLES = MotorConstants().pole_pairs


def _quality(channels: dict[str, np.ndarray]) -> dict[str, dict[str, float]]:
    return flight_quality(channels, screw_radius_m=RADIUS, pole_pairs=POLES)


def _holds_and_moves(n: int) -> np.ndarray:
    """A motor angle [rad] holding for 2 s, then moving at 20 rad/s for 1 s, repeated."""
    t = np.arange(n) / FS
    phase = t % 3.0
    moves = np.floor(t / 3.0)
    return 20.0 * (moves + np.clip(phase - 2.0, 0.0, 1.0))


def _channels(n: int, rng: np.random.Generator, *, sigma: dict[str, float],
              lvdt_offset_m: float = 0.0, gap_m: float = 0.0,
              ripple_a: float = 0.0) -> dict[str, np.ndarray]:
    """Three drives holding and moving; balanced phase currents (``ripple_a``: a drive's own
    ripple, common to the three phases' sum zero) whose torque sign flips every 6 s; the
    screw's nut on one flank or the other of a gap ``gap_m`` with that sign."""
    theta = _holds_and_moves(n)
    t = np.arange(n) / FS
    sign = np.where(np.floor(t / 6.0) % 2 == 0, 1.0, -1.0)
    th_e = POLES * theta
    amp = 1.0 + ripple_a * np.sin(2 * np.pi * 170.0 * t)
    # i_q = amp * sign with i_d = 0: phase currents of a balanced set
    i_al, i_be = -amp * sign * np.sin(th_e), amp * sign * np.cos(th_e)
    phases = {"ia": i_al, "ib": -0.5 * i_al + np.sqrt(3) / 2 * i_be,
              "ic": -0.5 * i_al - np.sqrt(3) / 2 * i_be}
    out: dict[str, np.ndarray] = {"t": t}
    for p in POSITIONS:
        out[f"{p}.theta"] = theta + rng.normal(0.0, sigma["theta"], n)
        out[f"{p}.x"] = (RADIUS * theta + lvdt_offset_m + 0.5 * gap_m * sign
                         + rng.normal(0.0, sigma["x"], n))
        for s, i in phases.items():
            out[f"{p}.{s}"] = i + rng.normal(0.0, sigma[s], n)
        for s in ("va", "vb", "vc"):
            out[f"{p}.{s}"] = 14.0 + rng.normal(0.0, sigma[s], n)
    return out


SIGMA = {"ia": 0.04, "ib": 0.04, "ic": 0.04, "va": 0.8, "vb": 0.8, "vc": 0.8,
         "theta": 2e-4, "x": 2e-6}


def test_the_noise_floor_is_the_white_noise_on_holds() -> None:
    rng = np.random.default_rng(1)
    ch = _channels(48_000, rng, sigma=SIGMA)
    q = _quality(ch)
    still = still_samples(ch["WT.theta"])
    for s in SIGNALS:
        # winsorised at 4 sigma: the estimate is within 2 % of the noise it was given
        assert channel_quality(ch[f"WT.{s}"], still)["noise"] == pytest.approx(SIGMA[s], rel=0.02)
    # the flight's figures: the resolver's and LVDT's own floors, the phases' on their sums
    assert [s for s in SIGNALS if "noise" in q[f"WT.{s}"]] == ["theta", "x"]
    assert q["WT.x"]["noise"] == pytest.approx(SIGMA["x"], rel=0.02)
    assert q["WT.i_sum"]["noise"] == pytest.approx(SIGMA["ia"], rel=0.02)
    assert q["WT.v_sum"]["noise"] == pytest.approx(SIGMA["va"], rel=0.02)


def test_a_doubled_noise_doubles_the_floor_of_that_channel_only() -> None:
    rng = np.random.default_rng(2)
    noisy = dict(SIGMA, x=4e-6)
    q = _quality(_channels(48_000, rng, sigma=noisy))
    base = _quality(_channels(48_000, np.random.default_rng(3), sigma=SIGMA))
    assert q["WL1.x"]["noise"] / base["WL1.x"]["noise"] == pytest.approx(2.0, rel=0.03)
    assert q["WL1.i_sum"]["noise"] / base["WL1.i_sum"]["noise"] == pytest.approx(1.0, rel=0.03)


def test_a_drive_ripple_leaves_the_current_sensor_floor_alone() -> None:
    """Ripple of the drive itself (an open inverter leg, a shorted turn) is in the true
    currents, whose sum is zero: the phase floors rise, the sensors' floor does not."""
    rippled_ch = _channels(48_000, np.random.default_rng(2), sigma=SIGMA, ripple_a=0.5)
    base_ch = _channels(48_000, np.random.default_rng(3), sigma=SIGMA)
    rippled, base = _quality(rippled_ch), _quality(base_ch)

    def phase_floor(ch: dict[str, np.ndarray]) -> float:
        return channel_quality(ch["WT.ia"], still_samples(ch["WT.theta"]))["noise"]

    assert phase_floor(rippled_ch) > 3 * phase_floor(base_ch)
    assert rippled["WT.i_sum"]["noise"] == pytest.approx(base["WT.i_sum"]["noise"], rel=0.03)


def test_moves_do_not_count_as_noise() -> None:
    theta = _holds_and_moves(48_000)
    still = still_samples(theta)
    assert 0.5 < still.mean() < 0.7  # 2 s holds of 3 s, minus the edges of each move
    assert not still[(np.arange(theta.size) / FS % 3.0 > 2.05)
                     & (np.arange(theta.size) / FS % 3.0 < 2.95)].any()


def test_step_stuck_and_rail_are_measured() -> None:
    rng = np.random.default_rng(4)
    n = 16_000
    still = np.ones(n, dtype=bool)
    lsb = 2.0**-5
    v = np.round((1.0 + rng.normal(0.0, 0.04, n)) / lsb) * lsb
    assert channel_quality(v, still)["lsb"] == pytest.approx(lsb)
    frozen = v.copy()
    frozen[4000:4800] = frozen[4000]  # 1 s frozen
    assert channel_quality(frozen, still)["stuck"] == pytest.approx(800 / n, rel=0.01)
    assert channel_quality(v, still)["stuck"] == 0.0
    # a slow swing clipped at a rail sits on it for whole spans
    swing = 1.5 * np.sin(2.0 * np.pi * 0.5 * np.arange(n) / FS) + rng.normal(0.0, 0.04, n)
    clipped = np.minimum(np.round(swing / lsb) * lsb, 1.0)
    share = float(np.mean(clipped == 1.0))
    assert channel_quality(clipped, still)["saturated"] == pytest.approx(share, rel=0.02)
    assert channel_quality(v, still)["saturated"] < 0.001


def test_lvdt_offset_against_the_motor_shaft_whatever_the_screw_gap() -> None:
    for gap in (0.0, 80e-6):  # a worn screw puts the nut 40 um either side
        q = _quality(_channels(24_000, np.random.default_rng(5), sigma=SIGMA,
                               lvdt_offset_m=40e-6, gap_m=gap))
        assert q["WT.x"]["offset"] == pytest.approx(40e-6, abs=0.5e-6)


def test_a_flight_without_holds_has_no_floor() -> None:
    n = 8000
    theta = 20.0 * np.arange(n) / FS  # always moving
    q = channel_quality(np.ones(n), still_samples(theta), QualityConfig())
    assert np.isnan(q["noise"])


def _simulated(sensor_faults: tuple[str, ...]) -> dict[str, dict[str, float]]:
    aircraft = fleet_for("design", 1, sensor_faults=sensor_faults)[0]
    log, _ = simulate_flight(aircraft, healthy(), 3, np.random.default_rng(7), duration_s=20.0)
    assert isinstance(log, FlightLog)
    return _quality({k: np.asarray(v, dtype=np.float64) for k, v in log.channels.items()})


@pytest.mark.parametrize(("fault", "channel"), [("WT.lvdt:noise=3", "WT.x"),
                                                ("WL1.current:noise=3", "WL1.i_sum"),
                                                ("WL2.voltage:noise=3", "WL2.v_sum")])
def test_a_sensor_flown_noisier_is_the_one_whose_floor_rises(fault: str, channel: str) -> None:
    """In the simulator's closed loops a sensor flown with three times its noise triples its
    floor (less where its quantisation step is near its noise), while every other sensor's
    floor stays within 10 %: the loops react to the noisier feedback, but the currents' sum,
    the voltages' common mode, the resolver and the other LVDTs do not carry that."""
    base, noisy = _simulated(()), _simulated((fault,))
    floors = [f"{p}.{c}" for p in POSITIONS for c in FLOOR_CHANNELS]
    ratio = {ch: noisy[ch]["noise"] / base[ch]["noise"] for ch in floors}
    assert 2.6 < ratio[channel] < 3.1
    assert max(abs(r - 1.0) for ch, r in ratio.items() if ch != channel) < 0.1


def _array_counts(v: np.ndarray, min_len: int) -> tuple[float, int, int]:
    """The step, stuck and rail counts in array form (what the compiled pass replaced)."""
    def in_runs(mask: np.ndarray, least: int) -> int:
        edges = np.diff(np.r_[False, mask, False].astype(np.int8))
        lengths = np.flatnonzero(edges == -1) - np.flatnonzero(edges == 1)
        return int(lengths[lengths >= least].sum())
    steps = np.diff(v)
    moved = np.abs(steps[steps != 0.0])
    lsb = float(moved.min()) if moved.size else float("nan")
    return lsb, in_runs(steps == 0.0, min_len), in_runs((v == v.max()) | (v == v.min()), 2)


@pytest.mark.parametrize("seed", range(6))
def test_the_compiled_counts_equal_the_array_forms(seed: int) -> None:
    rng = np.random.default_rng(seed)
    v = np.round(rng.normal(0.0, 3.0, 5000)) * 0.25  # quantised: many zero steps
    v[1000:1100 + 40 * seed] = v[1000]  # a frozen span
    v = np.clip(v, -2.0, 2.5)  # rails
    if seed == 4:
        v[2500] = np.nan
    if seed == 5:
        v[:] = 1.0  # never moves
    lsb, stuck, sat = channel_counts(v, float(v.max()), float(v.min()), 80)
    want = _array_counts(v, 80)
    assert (stuck, sat) == want[1:]
    assert lsb == want[0] or (np.isnan(lsb) and np.isnan(want[0]))
