"""The shipped model's design flies as a fleet and the test station fly: recording lengths drawn
per flight, the station's conditions in blocks of a healthy life; and F_MTEL's baseline sees
the hinge load through its drag weight."""

from __future__ import annotations

from collections import Counter
from dataclasses import replace

import numpy as np
import pytest

from server.phm.baselines import _covariates_for
from server.phm.recording import log_features
from sim_worker.campaign import (
    SCALES,
    STATION_ENVELOPE,
    block_conditions,
    plan_campaign,
    recording_s,
)
from sim_worker.campaign.run import _config_settings
from sim_worker.conditions import NO_CONDITIONS, Conditions
from sim_worker.faults import healthy
from sim_worker.flight import simulate_flight

CFG = SCALES["shipped"]["design"]


def test_recordings_are_drawn_per_flight_and_twins_draw_the_same() -> None:
    specs = plan_campaign("design", 1, "shipped")
    first = specs[0]
    drawn = Counter(recording_s(CFG, first, i) for i in range(first.n_flights))
    assert set(drawn) == {60.0, 120.0, 300.0}
    assert drawn[60.0] > drawn[120.0] and drawn[60.0] > drawn[300.0]  # 3 of 5 choices
    twin = next(s for s in specs if s.twin == first.id)
    assert all(recording_s(CFG, twin, i) == recording_s(CFG, first, i) for i in range(50))
    # a scale without recordings flies its one duration
    quick = SCALES["quick"]["design"]
    assert recording_s(quick, first, 3) == quick.duration_s


def test_conditions_come_in_blocks_after_a_nominal_first_one() -> None:
    spec = plan_campaign("design", 1, "shipped")[0]
    flown = [block_conditions(CFG, spec, i) for i in range(spec.n_flights)]
    assert all(c == NO_CONDITIONS for c in flown[:CFG.condition_blocks])
    blocks = [flown[i:i + CFG.condition_blocks] for i in range(0, len(flown),
                                                                CFG.condition_blocks)]
    assert all(len(set(b)) == 1 for b in blocks)
    conditioned = [b[0] for b in blocks if b[0] != NO_CONDITIONS]
    assert conditioned
    for c in conditioned:
        lo, hi = STATION_ENVELOPE["ambient_offset_k"]
        assert lo <= c.ambient_offset_k <= hi
        for name in ("load_scale", "command_scale"):
            lo, hi = STATION_ENVELOPE[name]
            assert lo <= getattr(c, name) <= hi
    # fault patterns fly as drawn
    fault = next(s for s in plan_campaign("design", 1, "shipped") if s.mode == "TTS")
    assert block_conditions(CFG, fault, 200) == NO_CONDITIONS


def test_scales_without_the_envelope_keep_their_settings() -> None:
    """Finished campaigns of the other scales are recognised by their settings: the new
    fields appear only where a scale uses them."""
    assert "recordings_s" not in _config_settings(SCALES["protocol"]["design"])
    assert "condition_blocks" not in _config_settings(SCALES["quick"]["verification"])
    assert _config_settings(CFG)["condition_blocks"] == 40


def test_a_winglet_drives_friction_ratio_is_linear_in_its_drag_weight() -> None:
    """The active winglet drive back-drives its attached standby, whose drag does not grow
    with the hinge load: under the test station's load scale its F_MTEL falls, on the line
    of the drag weight 1 / (T_ref + |L|), which F_MTEL's baseline takes as a covariate. The
    wingtip has no standby and barely moves."""
    from sim_worker.campaign import fleet_for

    aircraft = fleet_for("design", 1)[0]
    mtel, weight = {}, {}
    for scale in (0.5, 1.0, 2.0):
        log, _ = simulate_flight(aircraft, healthy(), 3, np.random.default_rng([5, 3, 0]),
                                 duration_s=60.0, conditions=Conditions(load_scale=scale))
        f = log_features(log)
        mtel[scale] = {p: f.summaries[f"{p}.F_MTEL"].value for p in ("WL2", "WT")}
        weight[scale] = f.conditions["WL2"]["mtel_drag_weight_per_nm"]
    assert weight[0.5] > weight[1.0] > weight[2.0]
    slope = (mtel[0.5]["WL2"] - mtel[2.0]["WL2"]) / (weight[0.5] - weight[2.0])
    assert slope > 0.05
    on_line = mtel[2.0]["WL2"] + slope * (weight[1.0] - weight[2.0])
    assert mtel[1.0]["WL2"] == pytest.approx(on_line, rel=0.03)
    assert abs(mtel[0.5]["WT"] - mtel[2.0]["WT"]) < 0.2 * abs(mtel[0.5]["WL2"] - mtel[2.0]["WL2"])
    assert "mtel_drag_weight_per_nm" in _covariates_for("WL2.F_MTEL", ())
    assert "mtel_drag_weight_per_nm" not in _covariates_for("WL2.F_DMD", ())


def test_recording_lengths_out_of_range_are_refused(tmp_path) -> None:  # type: ignore[no-untyped-def]
    from sim_worker.campaign import run_campaign

    for bad in ((), (5.0,), (60.0, float("nan")), (1000.0,)):
        with pytest.raises(ValueError, match="recording lengths"):
            run_campaign("design", tmp_path, seed=1, scale="ci", recordings_s=bad,
                         progress=False)
    assert replace(CFG, recordings_s=(60.0,)).recordings_s == (60.0,)
