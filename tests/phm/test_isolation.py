"""The ambiguity group of a winglet drive's alarm on a pair-coupled feature: both drives,
each with the probability that the movement is its own fault's."""

from __future__ import annotations

import math

import numpy as np
import pytest

from server.phm.detection import DetectionState, FaultDetector, update_units
from server.phm.detection.pair import PAIR_COUPLING, isolation_of, level_sd, pair_isolation


def test_the_drive_that_moved_further_leads_and_equal_levels_are_a_coin() -> None:
    assert pair_isolation(3.0, 1.4, 20, 20) > 0.5 > pair_isolation(1.4, 3.0, 20, 20)
    assert pair_isolation(2.0, 2.0, 20, 20) == pytest.approx(0.5)
    # symmetric: the two hypotheses' probabilities add to one
    assert pair_isolation(3.0, 1.4, 20, 12) + pair_isolation(1.4, 3.0, 12, 20) == \
        pytest.approx(1.0)


def test_the_log_odds_are_the_closed_form_with_equal_noise() -> None:
    l1, l2, n, k = 1.0, 0.6, 16, PAIR_COUPLING
    s2 = level_sd(n) ** 2
    log_odds = (1 - k ** 2) * (l1 ** 2 - l2 ** 2) / (2 * s2 * (1 + k ** 2))
    p = pair_isolation(l1, l2, n, n)
    assert math.log(p / (1 - p)) == pytest.approx(log_odds, rel=1e-9)


def test_more_residuals_make_a_surer_group_and_a_faulty_partner_pattern_is_named() -> None:
    # a drive risen by 2 with its partner at the coupling's share of it
    own, partner = 2.0, PAIR_COUPLING * 2.0
    few, many = pair_isolation(own, partner, 4, 4), pair_isolation(own, partner, 30, 30)
    assert 0.5 < few < many
    # a drive showing only the coupling's share of its partner's rise is the partner's
    assert pair_isolation(partner, own, 30, 30) < 0.1


def test_a_level_against_the_fault_s_direction_is_no_evidence_and_none_leaves_it_alone() \
        -> None:
    assert pair_isolation(2.0, -5.0, 20, 20) == pair_isolation(2.0, 0.0, 20, 20)
    assert pair_isolation(2.0, -math.inf, 20, 0) == 1.0


def test_isolation_of_names_both_drives_only_for_coupled_evidence() -> None:
    levels = {"WL1": {"WL1.F_MTEL": 3.0}, "WL2": {"WL2.F_MTEL": 1.2}, "WT": {}}
    counts = {"WL1": {"WL1.F_MTEL": 20}, "WL2": {"WL2.F_MTEL": 20}, "WT": {}}
    group = isolation_of("WL1", ["WL1.F_MTEL"], levels, counts)
    assert set(group) == {"WL1", "WL2"} and group["WL1"] > 0.5
    assert sum(group.values()) == pytest.approx(1.0)
    # its own evidence besides the coupled feature: the unit's own
    assert isolation_of("WL1", ["WL1.F_MTEL", "WL1.F_DMD"], levels, counts) == {"WL1": 1.0}
    assert isolation_of("WT", ["WT.F_MTEL"], levels, counts) == {"WT": 1.0}
    # the partner not judged on the flight
    assert isolation_of("WL1", ["WL1.F_MTEL"], {"WL1": levels["WL1"]}, counts) == {"WL1": 1.0}


@pytest.mark.parametrize("faulty", ["WL1", "WL2"])
def test_the_judge_raises_a_friction_alarm_with_both_drives_named(faulty: str) -> None:
    """An MTEL drift on one drive, the coupling's share on its partner, each drive valid on
    alternate flights (active-standby): the faulty drive's alarm names both drives, itself the
    likelier; the other features' alarms would name their unit alone."""
    rng = np.random.default_rng(3)
    names = ["WL1.F_MTEL", "WL2.F_MTEL"]
    det = FaultDetector().fit([rng.standard_normal((200, 2)) for _ in range(8)], names)
    states = {u: DetectionState.new(u, [f"{u}.F_MTEL"]) for u in ("WL1", "WL2")}
    raised, last = {}, {}
    for k in range(300):
        active = "WL1" if k % 2 == 0 else "WL2"
        rise = 0.05 * max(k - 20, 0) * (1.0 if active == faulty else PAIR_COUPLING)
        z = {n: math.nan for n in names}
        z[f"{active}.F_MTEL"] = float(rng.standard_normal()) + rise
        for u, r in update_units(det, states, z).items():
            if r.new_alarm:
                raised[u] = r.isolation
            assert bool(r.isolation) == r.alarm  # a group while the alarm stands, none before
            if r.alarm:
                last[u] = r.isolation
    assert list(raised) == [faulty]
    group = raised[faulty]
    assert set(group) == {"WL1", "WL2"} and group[faulty] > 0.5
    # as the fault grows the two drives' levels part: the group grows surer
    assert last[faulty][faulty] >= group[faulty] and last[faulty][faulty] > 0.99
