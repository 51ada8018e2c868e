"""Which modes an actuator in alarm carries: the leading one and every other mode whose own
probability says it is present too (two degradations at once, a screw wearing while its
lubricant ages).

The softmax of :class:`~.estimator.FaultClassifier` names one mode: its probabilities compete,
so two modes present at once share the mass and neither need lead clearly. Each mode's own
probability (Platt's sigmoid on its one-vs-rest decision value, pooled over the flights since
the alarm by the chain) does not compete: the set is the leading mode, every other mode at or
above ``threshold`` and every mode whose own feature is beyond the leading mode's cross-talk
(:mod:`.crosstalk`), the most probable first. The set is provisional on each flight, as the
leading mode is; the threshold is chosen on concurrent design campaigns (``bench/mode_sets.py``,
docs/TUNING.md).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

__all__ = ["ModeSetRule", "MODE_SET", "modes_present", "named_by_feature"]


@dataclass(frozen=True)
class ModeSetRule:
    #: a mode other than the leading one joins the set at this own probability or above
    threshold: float = 0.6

    def __post_init__(self) -> None:
        if not 0.0 < self.threshold <= 1.0:
            raise ValueError("a mode set's threshold is a probability in (0, 1]")


#: the rule the service runs: chosen on design seeds (bench/mode_sets.py, docs/TUNING.md)
MODE_SET = ModeSetRule()


def modes_present(leader: str, own: Mapping[str, float], rule: ModeSetRule = MODE_SET,
                  beyond: Sequence[str] = ()) -> list[str]:
    """The leading mode, then every other mode whose own probability in ``own`` is at least
    the rule's threshold or that is in ``beyond`` (its own feature beyond the leading mode's
    cross-talk), the most probable first."""
    others = {m for m, q in own.items() if q >= rule.threshold} | set(beyond)
    others.discard(leader)
    return [leader, *sorted(others, key=lambda m: (-own.get(m, 0.0), m))]


def named_by_feature(modes: Sequence[str], own: Mapping[str, float],
                     rule: ModeSetRule = MODE_SET) -> list[str]:
    """The modes beside the leading one in ``modes`` whose own probability is below the
    rule's threshold: named by their own feature beyond the leading mode's cross-talk."""
    return [m for m in modes[1:] if own.get(m, 0.0) < rule.threshold]
