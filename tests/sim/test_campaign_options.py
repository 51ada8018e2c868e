"""Robustness options of campaigns: other bases, scaled sensor noise, one degraded sensor;
tails and seeds fixed."""

from __future__ import annotations

import pickle
from dataclasses import replace

import numpy as np
import pytest

from server.flightlog import FlightLog
from server.vocabulary import POSITIONS, SENSORS
from sim_worker.campaign import (
    SCALES,
    SENSOR_STUDY_FLIGHTS,
    SENSOR_STUDY_NOISE,
    ParquetSink,
    SensorFault,
    fleet_for,
    plan_campaign,
    run_campaign,
)
from sim_worker.campaign.pattern import _render
from sim_worker.campaign.run import _manifest, _Progress, _settings
from sim_worker.campaign.sensor_faults import at_flight, canonical_sensor_faults, with_sensor_noise
from sim_worker.cli import build_parser
from sim_worker.faults import MODES, healthy
from sim_worker.flight import draw_conditions, run_scenario, simulate_flights
from sim_worker.kernel import D
from sim_worker.scenario import build_scenario


def _render_now(*args):  # type: ignore[no-untyped-def]
    """A rendered flight of a pattern (:func:`_render`, a generator) flown at once."""
    run = _render(*args)
    try:
        run.send(simulate_flights([next(run)])[0])
    except StopIteration as done:
        return done.value
    raise AssertionError("a rendered flight yields one flight")


def test_noise_scale_multiplies_sensor_noise_only() -> None:
    nominal, noisy = fleet_for("verification", 2), fleet_for("verification", 2, noise_scale=2.0)
    assert [a.tail for a in nominal] == [a.tail for a in noisy]
    for a, b in zip(nominal, noisy, strict=True):
        assert a.seed == b.seed
        for pos in a.ema:
            sa, sb = a.ema[pos].sensors, b.ema[pos].sensors
            assert sb.current_noise_a == 2 * sa.current_noise_a
            assert sb.voltage_noise_v == 2 * sa.voltage_noise_v
            assert sb.lvdt_noise_m == 2 * sa.lvdt_noise_m
            assert sb.current_offset_a == sa.current_offset_a
            assert a.ema[pos].motor == b.ema[pos].motor


def test_bases_replace_the_climate_mix() -> None:
    mix = fleet_for("design", 1)
    assert [a.base for a in mix].count("Turin") == 4
    hot = fleet_for("design", 1, bases=("Abu Dhabi",))
    assert {a.base for a in hot} == {"Abu Dhabi"}
    assert [a.seed for a in hot] == [a.seed for a in mix]


def test_unknown_base_is_refused(tmp_path) -> None:
    with pytest.raises(ValueError, match="bases"):
        run_campaign("design", tmp_path, seed=1, bases=("Atlantis",), progress=False)


@pytest.mark.parametrize("bad", [0, -3, 2.5, True, 20])
def test_render_every_must_be_a_positive_odd_int(tmp_path, bad) -> None:
    """Odd: the winglet's active drive alternates by flight, and an even step would render a
    faulty winglet drive in one role only."""
    with pytest.raises(ValueError, match="render_every"):
        run_campaign("design", tmp_path, seed=1, render_every=bad, progress=False)
    assert all(cfg.render_every % 2 == 1 for kinds in SCALES.values() for cfg in kinds.values())


# ---- sensor faults: one sensor of one actuator degraded on every aircraft -------------------


def test_sensor_fault_spec_round_trips() -> None:
    f = SensorFault.parse("WT.lvdt:noise=2")
    assert f == SensorFault("WT", "lvdt", "noise", 2.0)
    assert f.spec == "WT.lvdt:noise=2"
    for spec in ("WL1.lvdt:drift=1e-06", "WL2.current:noise=0.5", "WT.lvdt:drift=-3e-07"):
        assert SensorFault.parse(spec).spec == spec
    assert pickle.loads(pickle.dumps((f,))) == (f,)  # PatternTask options go to workers


@pytest.mark.parametrize(("spec", "message"), [
    ("WX.lvdt:noise=2", "unknown position"),
    ("WT.gyro:noise=2", "unknown sensor"),
    ("WT.lvdt:bias=2", "unknown sensor fault"),
    ("WT.current:drift=1e-6", "drift is an LVDT fault"),
    ("WT.lvdt:noise=0", "positive"),
    ("WT.lvdt:noise=-1", "positive"),
    ("WT.lvdt:noise=nan", "finite"),
    ("WT.lvdt:noise=inf", "finite"),
    ("WT.lvdt:drift=inf", "finite"),
    ("WT.lvdt:noise=two", "not a number"),
    ("WT.lvdt", "POSITION.SENSOR"),
    ("lvdt:noise=2", "POSITION.SENSOR"),
])
def test_bad_sensor_fault_specs_say_what_is_wrong(spec, message) -> None:
    with pytest.raises(ValueError, match=message):
        SensorFault.parse(spec)


def test_noise_fault_scales_one_sensor_of_one_actuator() -> None:
    nominal = fleet_for("design", 3)
    faulty = fleet_for("design", 3, noise_scale=2.0,
                       sensor_faults=("WT.lvdt:noise=3", "WL1.current:noise=0.5"))
    for a, b in zip(nominal, faulty, strict=True):
        assert b.offsets == a.offsets
        for pos in POSITIONS:
            sa, sb = a.ema[pos].sensors, b.ema[pos].sensors
            # combined multiplicatively with the campaign's noise scale
            assert sb.lvdt_noise_m == pytest.approx(sa.lvdt_noise_m * (6 if pos == "WT" else 2))
            assert sb.current_noise_a == pytest.approx(
                sa.current_noise_a * (1 if pos == "WL1" else 2))
            assert sb.voltage_noise_v == pytest.approx(2 * sa.voltage_noise_v)
            assert sb.resolver_noise_rad == pytest.approx(2 * sa.resolver_noise_rad)


def test_drift_leaves_the_fleet_as_rigged() -> None:
    nominal = fleet_for("design", 3)
    drifting = fleet_for("design", 3, sensor_faults=(SensorFault.parse("WT.lvdt:drift=1e-5"),))
    assert [a.offsets for a in drifting] == [a.offsets for a in nominal]
    assert [a.ema for a in drifting] == [a.ema for a in nominal]


def test_same_sensor_fault_twice_is_refused(tmp_path) -> None:
    with pytest.raises(ValueError, match="twice"):
        run_campaign("design", tmp_path, seed=1, progress=False,
                     sensor_faults=("WT.lvdt:noise=2", "WT.lvdt:noise=3"))


def test_sensor_faults_are_campaign_settings(tmp_path) -> None:
    cfg = SCALES["ci"]["design"]
    opts = {"bases": None, "noise_scale": 1.0}
    plain = _settings("design", 1, "ci", cfg, {**opts, "sensor_faults": ()}, ParquetSink())
    faults = canonical_sensor_faults(["WT.lvdt:noise=2", "WL1.lvdt:drift=1e-06"])
    faulty = _settings("design", 1, "ci", cfg, {**opts, "sensor_faults": faults}, ParquetSink())
    assert "sensor_faults" not in plain  # campaigns made before the option stay recognised
    assert faulty["sensor_faults"] == ["WL1.lvdt:drift=1e-06", "WT.lvdt:noise=2"]  # canonical
    assert plain["winglet_mode"] == "active-standby"
    _Progress(tmp_path, plain)
    with pytest.raises(ValueError, match="other settings"):
        _Progress(tmp_path, faulty)  # resuming with other sensor faults is refused
    fleet = fleet_for("design", 1)
    assert _manifest(plain, cfg, fleet, [])["sensor_faults"] == []
    assert _manifest(faulty, cfg, fleet, [])["sensor_faults"] == faulty["sensor_faults"]


class _Keep:
    """A sink that keeps the rendered log in memory."""

    def __init__(self) -> None:
        self.logs: dict[int, FlightLog] = {}

    def __call__(self, out_dir, rel, index, log, ground_temp_c):
        self.logs[index] = log
        return None, None

    def describe(self):
        return {"sink": "keep"}

    def finish(self, out_dir, stored):
        return None


def _rendered_x(tmp_path, faults: tuple[SensorFault, ...], index: int) -> dict[str, np.ndarray]:
    aircraft = fleet_for("design", 1)[0]
    spec = plan_campaign("design", 1, "ci")[0]
    sink = _Keep()
    _render_now(tmp_path, aircraft, spec, healthy(), index,
            replace(SCALES["ci"]["design"], duration_s=4.0), sink, faults)
    return {pos: sink.logs[index].channels[f"{pos}.x"].astype(float) for pos in POSITIONS}


def test_lvdt_drift_shifts_the_rendered_winglet_lvdts(tmp_path) -> None:
    """The tab's position loop closes on the active drive's LVDT: a drifted standby LVDT
    reads the offset and moves nothing; a drifted active one moves the tab by the offset,
    which its partner reads with the opposite sign."""
    drift = 2e-5
    faults = (SensorFault.parse(f"WL1.lvdt:drift={drift}"),)
    lsb = 2.0**-19
    # flight 5: WL1 stands by, it reads the offset; flight 4: WL1 drives, WL2 reads -offset
    for index, wl1_reads, wl2_reads in ((5, 1.0, 0.0), (4, 0.0, -1.0)):
        base, drifted = _rendered_x(tmp_path, (), index), _rendered_x(tmp_path, faults, index)
        shift = {pos: float(np.median(drifted[pos] - base[pos])) for pos in POSITIONS}
        assert shift["WL1"] - shift["WL2"] == pytest.approx(drift * index, abs=2 * lsb)
        assert shift["WL1"] == pytest.approx(wl1_reads * drift * index, abs=2 * lsb)
        assert shift["WL2"] == pytest.approx(wl2_reads * drift * index, abs=2 * lsb)
        assert shift["WT"] == 0.0
    # flight 0 is the rigged one
    assert np.array_equal(_rendered_x(tmp_path, faults, 0)["WL1"],
                          _rendered_x(tmp_path, (), 0)["WL1"])


def test_lvdt_drift_moves_the_wingtip_rod_under_its_own_loop() -> None:
    aircraft = fleet_for("design", 1)[0]
    drift, index = 2e-5, 5
    flown = at_flight(aircraft, (SensorFault.parse(f"WT.lvdt:drift={drift}"),), index)
    assert flown.offsets["WT"][3] == pytest.approx(aircraft.offsets["WT"][3] + drift * index)
    assert flown.offsets["WL1"] == aircraft.offsets["WL1"]
    k = POSITIONS.index("WT")

    def rod(ac):
        rng = np.random.default_rng(7)
        cond = draw_conditions(ac, index, rng)
        return run_scenario(ac, healthy(), build_scenario(cond.warp, cond.ground_temp_c, rng,
                                                          duration_s=4.0), rng).truth[:, k, D.XROD]

    # the single wingtip LVDT is its loop's feedback: the true rod sits off by -offset
    assert float(np.median(rod(flown) - rod(aircraft))) == pytest.approx(-drift * index,
                                                                           rel=0.05)


@pytest.mark.parametrize(("args", "message"), [
    (["--sensor-fault", "WT.current:drift=1e-6"], "drift is an LVDT fault"),
    (["--sensor-fault", "WT.lvdt:noise=2", "--sensor-fault", "WT.lvdt:noise=3"], "twice"),
])
def test_cli_refuses_a_bad_sensor_fault(capsys, args, message) -> None:
    with pytest.raises(SystemExit) as exc:
        build_parser().parse_args(["campaign", "--kind", "design", "--out", "x", *args])
    assert exc.value.code == 2
    assert message in capsys.readouterr().err


def test_cli_collects_sensor_faults() -> None:
    args = build_parser().parse_args(["campaign", "--kind", "design", "--out", "x",
                                      "--sensor-fault", "WT.lvdt:noise=2",
                                      "--sensor-fault", "WT.lvdt:drift=1e-6"])
    assert [f.spec for f in args.sensor_fault] == ["WT.lvdt:noise=2", "WT.lvdt:drift=1e-06"]
    assert build_parser().parse_args(["campaign", "--kind", "design", "--out", "x"]
                                     ).sensor_fault == []


def test_the_design_sensor_study_repeats_healthy_patterns_with_one_sensor_noisier() -> None:
    plan = plan_campaign("design", 1, "ci")
    by_id = {s.id: s for s in plan}
    study = [s for s in plan if s.sensor_study]
    assert [s.sensor_study for s in study] == [s for s in SENSORS for _ in range(2)]
    for s in study:
        twin = by_id[s.twin]
        assert twin.mode == "healthy" and twin.sensor_study is None
        assert (s.seed, s.aircraft_index, s.day_offset) == (
            twin.seed, twin.aircraft_index, twin.day_offset)
        assert s.n_flights == min(twin.n_flights, SENSOR_STUDY_FLIGHTS)
    assert [s.number for s in plan] == list(range(len(plan)))
    assert not any(s.sensor_study for s in plan_campaign("verification", 1, "ci"))


def test_protocol_healthy_cycles_run_as_long_as_the_faults() -> None:
    """The paper's healthy cycles lasted as long as its fault runs (150-400 flights); the
    design's run half a year each; lengths depend on the seed, not on the run."""
    ver = [s for s in plan_campaign("verification", 2, "protocol") if s.mode == "healthy"]
    des = [s for s in plan_campaign("design", 1, "protocol")
           if s.mode == "healthy" and not s.sensor_study]
    assert len(ver) == 25 and all(150 <= s.n_flights <= 400 for s in ver)
    assert len({s.n_flights for s in ver}) > 10  # drawn, not one length
    assert len(des) == 10 and all(300 <= s.n_flights <= 400 for s in des)
    again = [s for s in plan_campaign("verification", 2, "protocol") if s.mode == "healthy"]
    assert [s.n_flights for s in again] == [s.n_flights for s in ver]
    other = [s for s in plan_campaign("verification", 3, "protocol") if s.mode == "healthy"]
    assert [s.n_flights for s in other] != [s.n_flights for s in ver]
    study = [s for s in plan_campaign("design", 1, "protocol") if s.sensor_study]
    assert all(s.n_flights == SENSOR_STUDY_FLIGHTS for s in study)


@pytest.mark.parametrize("per_mode", [0, 1, 3])
def test_a_part_of_a_campaign_flies_the_same_patterns_as_the_whole(per_mode: int) -> None:
    whole = {s.id: s for s in plan_campaign("design", 1, "protocol")}
    part = plan_campaign("design", 1, "protocol", per_mode=per_mode)
    assert all(whole[s.id] == s for s in part)  # numbers, seeds and lengths unchanged
    faults = [s for s in part if s.mode != "healthy"]
    assert len(faults) == per_mode * 7
    assert sum(s.mode == "healthy" and not s.sensor_study for s in part) == 10
    assert any(s.sensor_study for s in part) == (per_mode > 0)


def test_a_study_flight_is_its_twin_with_one_sensor_noisier(tmp_path) -> None:
    """The same flight, seeds and noise draws: the resolver study's flight 0 has the twin's
    LVDT, current and voltage floors and twice its resolver floor."""
    from server.phm.features import MotorConstants
    from server.phm.signal_quality import flight_quality

    plan = plan_campaign("design", 1, "ci")
    study = next(s for s in plan if s.sensor_study == "resolver")
    twin = next(s for s in plan if s.id == study.twin)
    aircraft = fleet_for("design", 1)[study.aircraft_index]
    noisier = with_sensor_noise(aircraft, [SensorFault(p, "resolver", "noise",
                                                       SENSOR_STUDY_NOISE) for p in POSITIONS])
    mc = MotorConstants()
    floors = {}
    for name, spec, ac in (("twin", twin, aircraft), ("study", study, noisier)):
        sink = _Keep()
        _render_now(tmp_path, ac, spec, healthy(), 0,
                replace(SCALES["ci"]["design"], duration_s=10.0), sink)
        ch = {k: np.asarray(v, dtype=float) for k, v in sink.logs[0].channels.items()}
        floors[name] = flight_quality(ch, screw_radius_m=mc.screw_radius_m,
                                      pole_pairs=mc.pole_pairs)
    ratio = {c: floors["study"][f"WT.{c}"]["noise"] / floors["twin"][f"WT.{c}"]["noise"]
             for c in ("theta", "x", "i_sum", "v_sum")}
    assert ratio["theta"] == pytest.approx(SENSOR_STUDY_NOISE, rel=0.05)
    assert all(abs(ratio[c] - 1.0) < 0.05 for c in ("x", "i_sum", "v_sum"))


def test_a_negative_part_is_refused(tmp_path) -> None:
    with pytest.raises(ValueError, match="per_mode"):
        run_campaign("design", tmp_path, seed=1, scale="ci", per_mode=-1, progress=False)
    assert not any(tmp_path.iterdir())  # refused before anything is written


@pytest.mark.slow
def test_a_part_of_a_campaign_runs_to_its_manifest(tmp_path) -> None:
    """A part's patterns keep the whole campaign's numbers (the faults' run past the part's
    length): the run stores each under its own and writes the part's manifest."""
    manifest = run_campaign("verification", tmp_path, seed=1, scale="ci", per_mode=1,
                            progress=False, workers=1)
    want = [s.id for s in plan_campaign("verification", 1, "ci", per_mode=1)]
    assert [p["id"] for p in manifest["patterns"]] == want
    assert {p["mode"] for p in manifest["patterns"]} == {"healthy", *MODES}


def test_a_campaign_can_plan_more_fault_patterns_per_mode_than_its_scale() -> None:
    """``--patterns-per-mode`` plans that many patterns of every fault mode (the speed-group
    suite needs 10-20 where the quick scale has 3-6); ``per_mode`` still takes the first."""
    from collections import Counter

    from sim_worker.campaign.scales import scale_config

    plan = plan_campaign("verification", 1, "ci", patterns_per_mode=5)
    counts = Counter(s.mode for s in plan if s.mode != "healthy")
    assert counts == {m: 5 for m in MODES}
    assert len({s.seed for s in plan}) == len(plan)
    first = plan_campaign("verification", 1, "ci", patterns_per_mode=5, per_mode=2)
    assert Counter(s.mode for s in first if s.mode != "healthy") == {m: 2 for m in MODES}
    assert scale_config("ci", "design", None, None, patterns_per_mode=7).patterns_per_mode == 7
    for bad in (0, 100, True, 2.0):
        with pytest.raises(ValueError, match="patterns per mode"):
            scale_config("ci", "design", None, None, patterns_per_mode=bad)  # type: ignore[arg-type]
    args = build_parser().parse_args(["campaign", "--kind", "design", "--out", "x",
                                      "--patterns-per-mode", "12"])
    assert args.patterns_per_mode == 12


def test_step_fault_patterns_can_fly_longer_than_their_scale() -> None:
    """``--step-flights`` lengthens the SE and BDO patterns alone (a step fault stays until
    its unit is replaced: how many flights it takes to be found); every pattern keeps its
    number, seed and onset, so its first flights are the scale's."""
    from sim_worker.campaign.scales import MAX_STEP_FLIGHTS, scale_config

    short = {s.id: s for s in plan_campaign("verification", 1, "ci")}
    long = plan_campaign("verification", 1, "ci", step_flights=20)
    assert [s.id for s in long] == list(short)
    for s in long:
        was = short[s.id]
        assert (s.number, s.seed, s.onset) == (was.number, was.seed, was.onset)
        assert s.n_flights == (20 if s.mode in ("SE", "BDO") else was.n_flights)
    cfg = scale_config("ci", "verification", None, None, step_flights=20)
    assert cfg.apriori_flights == 20
    for bad in (cfg.apriori_onset, MAX_STEP_FLIGHTS + 1, True, 20.0):
        with pytest.raises(ValueError, match="step-fault patterns"):
            scale_config("ci", "verification", None, None, step_flights=bad)  # type: ignore[arg-type]
    args = build_parser().parse_args(["campaign", "--kind", "verification", "--out", "x",
                                      "--step-flights", "24"])
    assert args.step_flights == 24
