"""Flights, fleet, progression laws and campaign planning."""

from __future__ import annotations

import numpy as np
import pytest

from server.flightlog import OPTIONAL_CHANNELS, check_coherence, read_parquet, write_parquet
from sim_worker import advance_fault, build_aircraft, healthy, new_fault, simulate_flight
from sim_worker.campaign import fleet_for, plan_campaign
from sim_worker.faults import PROGRESSIVE, ActuatorSummary, FlightSummary


def _flight(seed: int, duration: float = 15.0) -> bytes:
    ac = build_aircraft("I-REPRO1", "Vancouver", seed=7)
    log, _ = simulate_flight(ac, healthy(), 3, np.random.default_rng([7, 3, seed]),
                             duration_s=duration)
    return write_parquet(log)


def test_same_seed_same_bytes_other_seed_other_bytes():
    assert _flight(1) == _flight(1)
    assert _flight(1) != _flight(2)


def test_flight_log_is_coherent_and_has_the_optional_channels():
    ac = build_aircraft("I-COHER1", "Abu Dhabi", seed=11)
    log, summary = simulate_flight(ac, healthy(), 0, np.random.default_rng(5), duration_s=20.0)
    assert check_coherence(log, fleet_serials=ac.serials) == []
    back = read_parquet(write_parquet(log))
    assert set(OPTIONAL_CHANNELS) <= set(back.channels)
    assert summary.measured and summary.actuators["WL1"].travel_m > 0.01
    # slow movements: most recorded time has the motor electrical frequency under 80 Hz
    theta = log.channels["WL1.theta"].astype(np.float64)
    f_el = np.abs(np.gradient(theta, log.channels["t"])) * 4 / (2 * np.pi)
    assert np.mean(f_el < 80.0) > 0.9


def _summary(temp_c: float, work: float) -> FlightSummary:
    a = ActuatorSummary(winding_mean_c=temp_c, winding_max_c=temp_c + 2, current_rms_a=3.0,
                        load_rms_n=1500.0, work_screw_n_m=work, work_rod_end_n_m=work,
                        travel_m=0.3)
    return FlightSummary(actuators={"WL1": a, "WL2": a, "WT": a}, block_hours=1.5,
                         ground_temp_c=temp_c, duration_s=120.0, measured=False)


def test_progression_follows_its_driver():
    ref = _summary(20.0, 200.0).actuators["WL1"]
    for mode in PROGRESSIVE:
        f0 = new_fault(mode, "WL1", np.random.default_rng(1), reference=ref)
        cool = advance_fault(f0, _summary(10.0, 100.0), np.random.default_rng(2))
        hot = advance_fault(f0, _summary(40.0, 400.0), np.random.default_rng(2))
        assert f0.severity < cool.severity < hot.severity, mode


def test_fault_to_failure_span_is_in_range():
    """Spans stay within U(170, 360) +- the process noise on either surface."""
    ref = _summary(20.0, 200.0).actuators["WL1"]
    rng = np.random.default_rng(4)
    for mode in PROGRESSIVE:
        for pos in ("WL1", "WT"):
            spans = []
            for k in range(5):
                f = new_fault(mode, pos, np.random.default_rng([k, 9]), reference=ref)
                n = 0
                while not f.failed and n < 2000:
                    f = advance_fault(f, _summary(20.0, 200.0), rng)
                    n += 1
                spans.append(n)
            assert 130 <= min(spans) and max(spans) <= 420, (mode, pos, spans)


def test_a_log_uniform_draw_spans_the_envelope_evenly_in_log():
    """Design campaigns draw spans log-uniformly over 30-1000 flights: as many runs below
    the geometric middle (173 flights) as above it, none outside the envelope."""
    from sim_worker.campaign import SCALES
    from sim_worker.faults import ENVELOPE_FLIGHTS, draw_span

    rng = np.random.default_rng(0)
    spans = np.array([draw_span(rng, ENVELOPE_FLIGHTS, "log") for _ in range(4000)])
    assert spans.min() >= 30.0 and spans.max() <= 1000.0
    assert 0.47 < np.mean(spans < np.sqrt(30.0 * 1000.0)) < 0.53
    # a uniform draw over the same range would put 7 % of its runs under 100 flights
    assert 0.31 < np.mean(spans < 100.0) < 0.38
    for scale in ("quick", "protocol"):
        cfg = SCALES[scale]["design"]
        assert (cfg.span_flights, cfg.span_draw) == (ENVELOPE_FLIGHTS, "log")
        assert SCALES[scale]["verification"].span_draw == "uniform"
    with pytest.raises(ValueError, match="span_draw"):
        draw_span(rng, ENVELOPE_FLIGHTS, "normal")


def test_verification_fleet_is_disjoint_from_design():
    d, v = fleet_for("design", 1), fleet_for("verification", 1)
    assert len(d) == len(v) == 10
    assert not {a.tail for a in d} & {a.tail for a in v}
    assert not {a.seed for a in d} & {a.seed for a in v}
    assert [a.base for a in d].count("Turin") == 4
    assert [a.base for a in d].count("Vancouver") == 3
    assert [a.base for a in d].count("Abu Dhabi") == 3


def test_campaign_plan_covers_every_mode():
    for kind in ("design", "verification"):
        specs = plan_campaign(kind, 3, "paper")
        modes = {s.mode for s in specs}
        assert modes == {"healthy", "TTS", "DMD", "SE", "BDO", "MTEL", "MTWEAR", "REWEAR"}
        assert all(s.position in ("WL1", "WL2") for s in specs if s.mode == "REWEAR")
    ver = plan_campaign("verification", 3, "paper")
    assert sum(s.mode == "TTS" for s in ver) == 25


@pytest.mark.slow
def test_tiny_campaign_manifest(tmp_path, monkeypatch):
    import json

    from sim_worker.campaign import SCALES, ScaleConfig, run_campaign

    cfg = ScaleConfig(duration_s=12.0, healthy_patterns=1, healthy_flights=2, patterns_per_mode=1,
                      render_every=10_001, apriori_flights=2, apriori_onset=1, lead_flights=2)
    monkeypatch.setitem(SCALES, "tiny", {"design": cfg, "verification": cfg})
    # render_every overrides the scale's step (still only onset and failure rendered here)
    run_campaign("design", tmp_path, seed=5, scale="tiny", workers=1, progress=False,
                 render_every=5_001)
    m = json.loads((tmp_path / "manifest.json").read_text())
    assert m["format"] == "ema-campaign/1" and m["kind"] == "design" and m["seed"] == 5
    assert m["render_every"] == 5_001
    assert {a["base"] for a in m["aircraft"]} == {"Turin", "Vancouver", "Abu Dhabi"}
    for p in m["patterns"]:
        assert {"id", "aircraft", "mode", "position", "threshold", "onset_flight",
                "failure_flight", "flights"} <= set(p)
        for f in p["flights"]:
            assert (tmp_path / f["file"]).is_file()
            assert {"flight", "index", "file", "severity", "severity_norm", "true_rul_flights",
                    "block_hours", "ground_temp_c"} <= set(f)
        if p["mode"] in PROGRESSIVE:
            last = p["flights"][-1]
            assert last["index"] == p["failure_flight"] and last["true_rul_flights"] == 0
            assert last["severity_norm"] >= 1.0 > p["flights"][0]["severity_norm"]
            assert 100 <= p["failure_flight"] <= 500
            # the healthy lead: two rendered healthy flights, then the fault at onset
            assert p["onset_flight"] == 2
            assert [f["index"] for f in p["flights"][:3]] == [0, 1, 2]
            assert [f["severity_norm"] for f in p["flights"][:2]] == [0.0, 0.0]
            assert p["flights"][2]["severity_norm"] == pytest.approx(0.05)
        if p["mode"] == "healthy":
            assert all(f["severity_norm"] == 0.0 for f in p["flights"])


@pytest.mark.parametrize(("mode", "position"), [("REWEAR", "WL1"), ("MTWEAR", "WL2"),
                                                ("MTWEAR", "WT")])
def test_an_operators_span_holds_on_average(mode, position):
    """What the test station does without steering: the rate is set against the aircraft's
    average flight (:func:`reference_summary`), then estimated flights advance the fault. Over
    eight runs the mean span is the operator's 60 flights within the process noise's scatter."""
    from sim_worker import build_aircraft, reference_summary
    from sim_worker.flight import estimate_summary, flight_start

    ac = build_aircraft("I-SPAN01", "Vancouver", seed=21)
    ref = reference_summary(ac, position, duration_s=30.0, seed=4)
    spans = []
    for run in range(8):
        fault = new_fault(mode, position, np.random.default_rng([run, 1]), reference=ref,
                          span_flights=60)
        n = 0
        while not fault.failed and n < 400:
            index = 1000 * run + n
            summ = estimate_summary(ac, index, np.random.default_rng([run, n]),
                                    started_at=flight_start(index), duration_s=30.0)
            fault = advance_fault(fault, summ, np.random.default_rng([run, n, 2]))
            n += 1
        spans.append(n)
    assert 45 <= np.mean(spans) <= 80, spans
