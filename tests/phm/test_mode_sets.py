"""The set of modes present (server.phm.classification.modes) and its state in the chain: the
leading mode first, every other at the threshold, the pooled decision values kept across a
restart and seeded for a state stored before them."""

from __future__ import annotations

import json

import pytest

from server.phm.chain import ActuatorHealth
from server.phm.classification.modes import MODE_SET, ModeSetRule, modes_present
from server.phm.detection import DetectionState


def test_the_leader_comes_first_then_every_other_mode_at_the_threshold() -> None:
    own = {"TTS": 0.95, "DMD": 0.72, "MTEL": 0.49, "SE": 0.5}
    assert modes_present("TTS", own, ModeSetRule(0.5)) == ["TTS", "DMD", "SE"]
    # the leading mode stays in the set even when its own probability is below the threshold
    assert modes_present("MTEL", own, ModeSetRule(0.9)) == ["MTEL", "TTS"]
    assert modes_present("TTS", own, ModeSetRule(1.0)) == ["TTS"]
    with pytest.raises(ValueError, match="threshold"):
        ModeSetRule(0.0)
    assert 0.0 < MODE_SET.threshold <= 1.0


def test_the_modes_and_pooled_decisions_survive_a_restart_and_a_rearm_clears_them() -> None:
    h = ActuatorHealth("WL1", DetectionState.new("WL1", ["WL1.F_TTS", "WL1.F_DMD"]))
    h.mode_decision, h.modes, h.fault_mode = {"TTS": 3.0, "DMD": 1.5}, ["TTS", "DMD"], "TTS"
    back = ActuatorHealth.from_dict(json.loads(json.dumps(h.to_dict())))
    assert (back.mode_decision, back.modes) == (h.mode_decision, h.modes)
    old = {k: v for k, v in h.to_dict().items() if k not in ("mode_decision", "modes")}
    assert (ActuatorHealth.from_dict(old).mode_decision, ActuatorHealth.from_dict(old).modes
            ) == (None, [])
    back.rearm()
    assert (back.mode_decision, back.modes) == (None, [])
