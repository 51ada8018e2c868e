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
    # a mode beyond the leader's cross-talk joins whatever its own probability, the leader
    # never twice
    assert modes_present("TTS", own, ModeSetRule(0.9), beyond=["MTEL", "TTS"]) == [
        "TTS", "MTEL"]
    with pytest.raises(ValueError, match="threshold"):
        ModeSetRule(0.0)
    assert 0.0 < MODE_SET.threshold <= 1.0


def test_the_modes_and_pooled_decisions_survive_a_restart_and_a_rearm_clears_them() -> None:
    h = ActuatorHealth("WL1", DetectionState.new("WL1", ["WL1.F_TTS", "WL1.F_DMD"]))
    h.mode_decision, h.modes, h.fault_mode = {"TTS": 3.0, "DMD": 1.5}, ["TTS", "DMD"], "TTS"
    h.mode_runs, h.confirmed_modes = {"DMD": 3}, ["DMD"]
    h.own_feature = {"TTS": 4.0, "DMD": 2.5}
    back = ActuatorHealth.from_dict(json.loads(json.dumps(h.to_dict())))
    assert (back.mode_decision, back.modes, back.mode_runs, back.confirmed_modes,
            back.own_feature) == (h.mode_decision, h.modes, h.mode_runs, h.confirmed_modes,
                                  h.own_feature)
    old = {k: v for k, v in h.to_dict().items()
           if k not in ("mode_decision", "modes", "own_feature")}
    assert (ActuatorHealth.from_dict(old).mode_decision, ActuatorHealth.from_dict(old).modes,
            ActuatorHealth.from_dict(old).own_feature) == (None, [], None)
    back.rearm()
    assert (back.mode_decision, back.modes, back.mode_runs, back.confirmed_modes,
            back.own_feature) == (None, [], {}, [], None)


def test_a_mode_beside_the_leader_is_confirmed_by_the_rule_on_its_own_evidence() -> None:
    """In the set on the rule's flights in a row, its own probability at the rule's on the
    last: confirmed; leaving the set starts its run again; the leader's run is not counted."""
    from server.phm.classification.confirmation import ConfirmationRule, advance_others

    rule = ConfirmationRule(flights=2, probability=0.8)
    runs, held = advance_others(rule, {}, ["TTS", "DMD"], {"TTS": 0.99, "DMD": 0.85})
    assert (runs, held) == ({"DMD": 1}, [])
    runs, held = advance_others(rule, runs, ["TTS", "DMD"], {"DMD": 0.7})
    assert (runs, held) == ({"DMD": 2}, [])  # long enough, not probable enough
    runs, held = advance_others(rule, runs, ["TTS", "DMD"], {"DMD": 0.9})
    assert held == ["DMD"]
    runs, _ = advance_others(rule, runs, ["TTS"], {"DMD": 0.9})
    assert runs == {}
    runs, held = advance_others(rule, runs, ["TTS", "DMD"], {"DMD": 0.9})
    assert (runs, held) == ({"DMD": 1}, [])


def test_a_mode_named_by_its_own_feature_is_confirmed_while_its_feature_stays_beyond() -> None:
    """A DMD beside a short named by its feature (own probability far below the rule's): its
    third flight in the set (the rule's feature flights) confirms it while its feature is
    beyond the short's cross-talk on that flight; the probability's two flights do not."""
    from server.phm.classification.confirmation import ConfirmationRule, advance_others

    rule = ConfirmationRule(flights=2, probability=0.9, feature_flights=3)
    runs: dict[str, int] = {}
    for _ in range(2):
        runs, held = advance_others(rule, runs, ["TTS", "DMD"], {"DMD": 0.1}, beyond=["DMD"])
        assert held == []
    _, held = advance_others(rule, runs, ["TTS", "DMD"], {"DMD": 0.1})
    assert held == []  # in the set, neither probable nor beyond on this flight
    _, held = advance_others(rule, runs, ["TTS", "DMD"], {"DMD": 0.1}, beyond=["DMD"])
    assert held == ["DMD"]
    with pytest.raises(ValueError):
        ConfirmationRule(feature_flights=0)


def test_a_mode_confirmed_as_the_class_is_not_confirmed_again_beside_a_new_leader() -> None:
    """The class TTS was confirmed; DMD now leads and TTS stands beside it long enough: no
    second confirmation of TTS (one event per mode and alarm)."""
    from server.phm.chain.run import _confirm_others

    h = ActuatorHealth("WL1", DetectionState.new("WL1", ["WL1.F_TTS", "WL1.F_DMD"]))
    h.confirmed_mode, h.modes = "TTS", ["DMD", "TTS"]
    for _ in range(3):
        assert _confirm_others(h, {"TTS": 0.99, "DMD": 0.99}, []) == []
    h.modes = ["DMD", "TTS", "MTEL"]
    confirmed = [_confirm_others(h, {"TTS": 0.99, "MTEL": 0.95}, []) for _ in range(2)]
    assert confirmed == [[], ["MTEL"]] and h.confirmed_modes == ["MTEL"]


def test_own_features_pool_as_the_decisions_and_an_older_state_starts_at_this_flight() -> None:
    """Two flights pooled as the chain pools (decayed mean); a state stored before the own
    features were kept takes its past flights as this one, so the pooled mean is this flight's."""
    import numpy as np

    from server.phm.chain.config import CHAIN
    from server.phm.chain.run import OWN_COLUMN, _pool_own_features, pooled_own_features

    h = ActuatorHealth("WL1", DetectionState.new("WL1", ["WL1.F_TTS", "WL1.F_DMD"]))
    x1, x2 = np.arange(7.0), np.arange(7.0) + 1.0
    for x in (x1, x2):  # as _classify: the flight's values, then its weight
        _pool_own_features(h, x)
        h.class_weight = CHAIN.class_evidence_decay * (h.class_weight or 0.0) + 1.0
    d = CHAIN.class_evidence_decay
    expect = (d * x1 + x2) / (d + 1.0)
    assert pooled_own_features(h) == pytest.approx(
        {m: expect[c] for m, c in OWN_COLUMN.items()})
    old = ActuatorHealth("WL1", DetectionState.new("WL1", ["WL1.F_TTS"]))
    old.class_log_prob, old.class_weight = {"TTS": -0.1}, 3.0
    _pool_own_features(old, x2)
    old.class_weight = d * old.class_weight + 1.0
    assert pooled_own_features(old) == pytest.approx({m: x2[c] for m, c in OWN_COLUMN.items()})
