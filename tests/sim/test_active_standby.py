"""Physics of the active-standby winglet: who carries the hinge moment, the standby's damping
currents and its lag behind the active drive across reversals, and the energy audit."""

from __future__ import annotations

from datetime import datetime, timezone

import numpy as np
import pytest

from server.flightlog import read_parquet, write_parquet
from server.phm.features import actuator_steps, standby_play_feature
from server.vocabulary import SIGNALS
from sim_worker.faults import THRESHOLDS, FaultState, FlightSummary, advance_fault, new_fault
from sim_worker.fleet import WingletMode, active_channels
from sim_worker.flight import estimate_summary, reference_summary, simulate_flight
from sim_worker.kernel import A, D
from sim_worker.params import P
from tests.sim.helpers import const, make_scenario, ramp, run

WL1, WL2 = 0, 1
WL1_DRIVES = ("WL1", "WT")  # WL2 in standby
WL2_DRIVES = ("WL2", "WT")  # WL1 in standby


def _triangle(amplitude_m: float, hz: float):
    return lambda t: amplitude_m * (2 / np.pi) * np.arcsin(np.sin(2 * np.pi * hz * t))


def _steady_strokes(t: np.ndarray, x: np.ndarray, after_s: float = 2.0,
                    settle_s: float = 0.4) -> tuple[np.ndarray, np.ndarray]:
    """Samples of steady extension and steady retraction of a triangle command, ``settle_s``
    after each reversal (the loop's lag and the crossing of the opened plays)."""
    v = np.gradient(x, t)
    n_settle = int(settle_s / (t[1] - t[0]))
    since = np.convolve(np.sign(v), np.ones(n_settle), mode="full")[: t.size]
    late = t > after_s
    return late & (since >= n_settle - 0.5), late & (since <= -(n_settle - 0.5))


def _k_rod(row: np.ndarray) -> float:
    """Rod-end stiffness: the link's series stiffness without the screw's."""
    return 1.0 / (1.0 / row[P.K_EQ] - 1.0 / row[P.K_SCREW])


def _winding(row: np.ndarray, tw: float) -> tuple[float, float]:
    """(R_s, psi) of a row at winding temperature ``tw``."""
    r = row[P.R0] * (1.0 + row[P.ALPHA_CU] * (tw - row[P.TREF]))
    psi = row[P.PSI0] * (1.0 + row[P.ALPHA_BR] * (tw - row[P.TREF])) * (1.0 - row[P.DMD_H])
    return r, psi


def test_active_drive_carries_the_whole_hinge_moment(aircraft):
    """Holding the tab against 2 x 1500 N: the active drive's link carries it; the standby
    holds at most what its screw's static friction keeps of the preload it had when the tab
    stopped (both drives active share it, tests/sim/test_physics.py)."""
    sc = make_scenario(3.0, lambda t: ramp(t, 0.5, 1.5, 0.0, 0.008), const(0.0),
                       const(-1500.0), const(0.0))
    res = run(aircraft, sc, active=WL1_DRIVES)
    hold = (sc.t >= 2.0) & (sc.t < 3.0)
    f_active, f_standby = res.truth[hold, WL1, D.F], res.truth[hold, WL2, D.F]
    np.testing.assert_allclose((f_active + f_standby).mean(), 2 * 1500.0, rtol=0.01)
    row = res.params[WL2]
    breakaway_n = row[P.TCS] / (row[P.ETA_B] * row[P.R_SCREW])
    assert np.abs(f_standby).max() <= breakaway_n < 0.03 * 3000.0
    # the standby's controller does not act: no current reference, no drive current
    assert np.all(res.truth[:, WL2, D.IQREF] == 0.0)
    assert np.abs(res.truth[hold, WL2, D.IQ]).max() < 0.01


def test_standby_currents_are_the_damping_currents_its_back_emf_drives(aircraft):
    """Back-driven at steady speed w, the standby's shorted windings carry
    i_q = -p psi w / (R_s + R_d) (the electrical time constant, 0.3 ms, is negligible at these
    speeds), its phase currents are that vector on the resolver angle, and the force it
    opposes is (damping torque + drag) / (eta_b r) as the screw is back-driven."""
    sc = make_scenario(6.0, _triangle(0.010, 0.5), const(0.0), const(-1000.0), const(0.0))
    res = run(aircraft, sc, active=WL1_DRIVES)
    row = res.params[WL2]
    up, down = _steady_strokes(sc.t, sc.x_cmd[:, 0])
    moving = up | down
    w = res.truth[moving, WL2, D.W]
    r_s, psi = _winding(row, float(res.truth[moving, WL2, D.TW].mean()))
    r_total = r_s + row[P.R_DAMP]
    iq_expected = -row[P.PP] * psi * w / r_total
    np.testing.assert_allclose(res.truth[moving, WL2, D.IQ], iq_expected, rtol=0.03, atol=0.01)
    assert np.abs(iq_expected).mean() > 0.4  # a current well above the sensors' noise
    # measured phase a against the damping vector on the measured angle (i_d ~ 0)
    theta_e = row[P.PP] * res.signals[moving, WL2, 6]
    ia_expected = -iq_expected * np.sin(theta_e)
    residual = res.signals[moving, WL2, 0] - ia_expected - row[P.OFF_IA]
    assert np.sqrt(np.mean(residual ** 2)) < 0.06  # A: sensor noise 0.04 A rms + LSB
    # the force the standby opposes to its rod
    b = 1.5 * row[P.PP] ** 2 * psi ** 2 / r_total
    f_expected = (b * np.abs(w) + row[P.TC]) / (row[P.ETA_B] * row[P.R_SCREW])
    np.testing.assert_allclose(np.abs(res.truth[moving, WL2, D.F]).mean(), f_expected.mean(),
                               rtol=0.05)
    # and the standby's terminals show only the drop across the damping star
    va_expected = -row[P.R_DAMP] * (res.truth[moving, WL2, D.IQ] * -np.sin(theta_e))
    assert np.sqrt(np.mean((res.signals[moving, WL2, 3] - va_expected) ** 2)) < 1.2  # V


def test_a_stuck_standby_s_currents_decay_to_zero_not_to_subnormal_floats(aircraft):
    """Holding still, the standby's shaft sticks and its currents decay geometrically; they end
    at 0, not on the smallest subnormal float, which x86 cores compute in microcode (a flight
    was four times slower on an Intel Xeon): no subnormal in any true state or output."""
    sc = make_scenario(3.0, lambda t: ramp(t, 0.5, 1.0, 0.0, 0.008), const(0.0),
                       const(-1500.0), const(0.0))
    res = run(aircraft, sc, active=WL1_DRIVES)
    tiny = np.finfo(np.float64).tiny
    for name in ("truth", "signals", "acc"):
        values = np.asarray(getattr(res, name))
        assert not np.any((values != 0.0) & (np.abs(values) < tiny)), name
    still = sc.t >= 2.5
    assert np.all(res.truth[still, WL2, D.W] == 0.0)  # stuck, the case that made subnormals
    assert np.all(res.truth[still, WL2, D.IQ] == 0.0)


@pytest.mark.parametrize("drives, load_n, lagging", [
    (WL1_DRIVES, 0.0, ("WL1", "WL2")),  # no hinge load: both rod ends change flank
    (WL1_DRIVES, -1500.0, ("WL2",)),  # one-sided load: the active stays on its flank
    (WL2_DRIVES, -1500.0, ("WL1",)),
])
def test_standby_lvdt_lags_by_the_rod_end_plays_that_change_flank(aircraft, drives, load_n,
                                                                  lagging):
    """Across a reversal the rod ends whose force changes sign open their play, so the lost
    motion of x_active - x_standby is the sum of those plays plus the change of the rod ends'
    deflections (force / k_rod). With no hinge load both change flank (the sum of the two
    plays); under a one-sided load the active drive stays on one flank and the lost motion is
    the standby's play alone. WL1's rod end is worn (0.2 mm added) so the two differ."""
    wear = 0.2e-3
    fault = FaultState("REWEAR", "WL1", wear, THRESHOLDS["REWEAR"])
    sc = make_scenario(8.0, _triangle(0.005, 0.25), const(0.0), const(load_n), const(0.0))
    res = run(aircraft, sc, fault=fault, active=drives)
    k_act, k_sb = (WL1, WL2) if drives == WL1_DRIVES else (WL2, WL1)
    up, down = _steady_strokes(sc.t, sc.x_cmd[:, 0])
    plays = {"WL1": res.params[WL1, P.BL_ROD], "WL2": res.params[WL2, P.BL_ROD]}
    assert plays["WL1"] > plays["WL2"] + 0.9 * wear
    f = res.truth[:, :, D.F]
    deflection = sum((f[up, k].mean() - f[down, k].mean()) / _k_rod(res.params[k])
                     * (1.0 if k == k_act else -1.0) for k in (k_act, k_sb))
    expected = sum(plays[p] for p in lagging) + deflection
    for x in (res.truth[:, :, D.XROD], res.signals[:, :, 7]):  # true rods, then the LVDTs
        d = x[:, k_act] - x[:, k_sb]
        lost = d[up].mean() - d[down].mean()
        assert lost == pytest.approx(expected, abs=2.5e-6)
    assert abs(deflection) < 10e-6  # the plays, not the compliance, make the lag


def test_power_balance_of_both_channels(aircraft):
    """The standby takes no electrical energy: the link's work back-drives it and ends in its
    copper, damping-resistor and screw-friction losses (and kinetic energy); the active's
    audit closes as with two active drives."""
    sc = make_scenario(6.0, _triangle(0.010, 0.5), const(0.0),
                       lambda t: -800.0 - 4.0e4 * _triangle(0.010, 0.5)(t), const(0.0))
    res = run(aircraft, sc, active=WL1_DRIVES)
    for k in (WL1, WL2):
        a = res.acc[k]
        ke = 0.5 * res.params[k, P.J] * res.truth[-1, k, D.W] ** 2
        losses = a[A.E_CU] + a[A.E_FRIC] + ke
        if k == WL2:
            assert abs(a[A.E_IN]) < 1e-3 * a[A.E_CU]
            np.testing.assert_allclose(-a[A.E_LINK], losses, rtol=0.02)
        else:
            np.testing.assert_allclose(a[A.E_IN], losses + a[A.E_LINK], rtol=0.03)


def test_open_mosfet_of_a_standby_inverter_changes_nothing(aircraft):
    """A base-drive-open MOSFET matters only while its inverter switches: with WL2 in standby
    its signals are those of a healthy WL2, bit for bit; with WL2 active they are not."""
    sc = make_scenario(3.0, _triangle(0.008, 0.5), const(0.0), const(-1000.0), const(0.0))
    bdo = FaultState("BDO", "WL2", 1.0, THRESHOLDS["BDO"])
    healthy_run = run(aircraft, sc, active=WL1_DRIVES)
    faulty_run = run(aircraft, sc, fault=bdo, active=WL1_DRIVES)
    np.testing.assert_array_equal(faulty_run.signals, healthy_run.signals)
    active_faulty = run(aircraft, sc, fault=bdo, active=WL2_DRIVES)
    active_healthy = run(aircraft, sc, active=WL2_DRIVES)
    assert not np.array_equal(active_faulty.signals[:, WL2], active_healthy.signals[:, WL2])


def test_every_surface_needs_an_active_drive(aircraft):
    sc = make_scenario(0.1, const(0.0), const(0.0), const(0.0), const(0.0))
    with pytest.raises(ValueError, match="leaves surface WL undriven"):
        run(aircraft, sc, active=("WT",))


def test_active_channel_alternates_by_flight_and_the_log_says_which(aircraft):
    """Redundancy management swaps the winglet's active channel every flight; the download's
    metadata names the flight's active drives and survives the Parquet round trip."""
    assert [active_channels(WingletMode.ACTIVE_STANDBY, n) for n in range(3)] == [
        WL1_DRIVES, WL2_DRIVES, WL1_DRIVES]
    assert active_channels(WingletMode.ACTIVE_ACTIVE, 1) == ("WL1", "WL2", "WT")
    start = datetime(2025, 3, 1, tzinfo=timezone.utc)
    for n, drives in ((0, WL1_DRIVES), (1, WL2_DRIVES)):
        log, _ = simulate_flight(aircraft, FaultState("healthy", None, 0.0, None), n,
                                 np.random.default_rng(n), started_at=start, duration_s=2.0,
                                 winglet_mode=WingletMode.ACTIVE_STANDBY)
        assert log.metadata.active_channels == drives
        assert read_parquet(write_parquet(log)).metadata.active_channels == drives
    # the default is the iron bird's active-standby tab; an active-active flight names none
    log, _ = simulate_flight(aircraft, FaultState("healthy", None, 0.0, None), 0,
                             np.random.default_rng(0), started_at=start, duration_s=2.0)
    assert log.metadata.active_channels == WL1_DRIVES
    log, _ = simulate_flight(aircraft, FaultState("healthy", None, 0.0, None), 0,
                             np.random.default_rng(0), started_at=start, duration_s=2.0,
                             winglet_mode=WingletMode.ACTIVE_ACTIVE)
    assert log.metadata.active_channels is None
    assert b"active_channels" not in write_parquet(log)


@pytest.mark.parametrize("mode, severity_norm", [("REWEAR", 0.0), ("REWEAR", 1.0),
                                                 ("MTWEAR", 1.0)])
def test_unrendered_flights_wear_a_drive_as_rendered_ones_do(aircraft, mode, severity_norm):
    """The campaign's fast path (estimate_summary) against the 12 kHz model on the sliding
    work that drives the wear of a winglet drive, worn or not, in either role: within 10 %
    per role over 8 flights (4 active, 4 standby), with no load-share correction."""
    field = {"REWEAR": "work_rod_end_n_m", "MTWEAR": "work_screw_n_m"}[mode]
    thr = THRESHOLDS[mode]
    fault = FaultState(mode, "WL1", severity_norm * thr, thr)
    works: dict[str, list[tuple[float, float]]] = {"active": [], "standby": []}
    for n in range(8):
        _, rendered = simulate_flight(aircraft, fault, n, np.random.default_rng([2, n]),
                                      duration_s=60.0, winglet_mode=WingletMode.ACTIVE_STANDBY)
        estimated = estimate_summary(aircraft, n, np.random.default_rng([2, n]),
                                     duration_s=60.0, winglet_mode=WingletMode.ACTIVE_STANDBY)
        role = "active" if "WL1" in active_channels(WingletMode.ACTIVE_STANDBY, n) else "standby"
        works[role].append((getattr(rendered.actuators["WL1"], field),
                            getattr(estimated.actuators["WL1"], field)))
    for role, pairs in works.items():
        sim, est = np.sum(pairs, axis=0)
        assert sim / est == pytest.approx(1.0, abs=0.10), role
    # the active does most of the wear (1.8 times the standby's work on these flights)
    assert np.mean(works["active"], axis=0)[0] > 1.5 * np.mean(works["standby"], axis=0)[0]


def test_active_standby_wear_spans_hold(aircraft):
    """Rates calibrated on the reference flight reach failure within U(170, 360) +- the process
    noise when the drive does its reference work every flight."""
    ref = reference_summary(aircraft, "WL1", duration_s=60.0, seed=3,
                            winglet_mode=WingletMode.ACTIVE_STANDBY)
    summary = FlightSummary(actuators={p: ref for p in ("WL1", "WL2", "WT")}, block_hours=1.5,
                            ground_temp_c=15.0, duration_s=60.0, measured=False)
    rng = np.random.default_rng(4)
    for mode in ("REWEAR", "MTWEAR"):
        spans = []
        for k in range(5):
            f = new_fault(mode, "WL1", np.random.default_rng([k, 9]), reference=ref)
            n = 0
            while not f.failed and n < 2000:
                f = advance_fault(f, summary, rng)
                n += 1
            spans.append(n)
        assert 130 <= min(spans) and max(spans) <= 420, (mode, spans)


@pytest.mark.parametrize("wear_m", [0.0, 0.2e-3, 1.5e-3])
def test_standby_play_feature_reads_the_standby_rod_end(aircraft, wear_m):
    """F_REWEAR of the standby (server.phm.features.standby_play_feature) from the recorded
    signals: its rod-end play within 5 um, new or worn to three quarters of the failure
    play, under a one-sided hinge load; no value where the load changes sign at every
    reversal (the active's play would add to the lost motion)."""
    fault = FaultState("REWEAR", "WL1", wear_m, THRESHOLDS["REWEAR"])
    for load_n, expect_value in ((-1500.0, True), (0.0, False)):
        sc = make_scenario(20.0, _triangle(0.005, 0.25), const(0.0), const(load_n),
                           const(0.0))
        res = run(aircraft, sc, fault=fault, active=WL2_DRIVES)
        sig = res.signals
        active_steps = actuator_steps({name: sig[:, WL2, i] for i, name in enumerate(SIGNALS)})
        play = standby_play_feature(sig[:, WL2, 7], sig[:, WL1, 7], sig[:, WL2, 6],
                                    sig[:, WL1, 6], active_steps.i_q).summary()
        if expect_value:
            assert play.n_valid >= 8
            assert play.value == pytest.approx(res.params[WL1, P.BL_ROD], abs=5e-6)
        else:
            assert play.n_valid == 0 and np.isnan(play.value)


def test_winglet_mode_may_be_given_by_its_name():
    assert active_channels("active-standby", 1) == WL2_DRIVES  # type: ignore[arg-type]
    assert active_channels("active-active", 1) == ("WL1", "WL2", "WT")  # type: ignore[arg-type]
    with pytest.raises(ValueError):
        active_channels("standby-standby", 0)  # type: ignore[arg-type]
