"""When an alarm's class is confirmed: provisional at the first alarm, confirmed once the
evidence has said the same for long enough.

The classifier names a leading mode on every flight from the alarm on (its probabilities
pooled over the flights since, ``server.phm.chain.run``). The rule confirms the leading mode
when it has led on ``flights`` consecutive classified flights and its probability on the last
of them is at least ``probability``: a second flight of evidence for a step fault, a margin
for a slow one. The alarm is raised at the first flight either way; the confirmation is its own
event. One function serves the chain (flight by flight, :func:`advance`) and the evaluation
(whole sequences, :func:`first_confirmation`), so the two cannot disagree.

A second mode present beside the leading one (:mod:`.modes`) is confirmed on its own evidence
(:func:`advance_others`): in the set on ``flights`` consecutive classified flights with its own
probability at least ``probability`` on the last of them, or in the set on ``feature_flights``
consecutive flights with its own feature beyond the leading mode's cross-talk
(:mod:`.crosstalk`) on the last. The feature is the evidence that named it when the
classifier's probability could not (a DMD beside a short: the short moves the DMD feature, and
the one-vs-rest SVM weighs it against DMD), so asking the probability would leave such a mode
provisional for ever. It asks more flights: on the concurrent design, 2 confirmed an MTEL
beside a winglet drive's MTWEAR that was not there (docs/TUNING.md).
"""

from __future__ import annotations

from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass

__all__ = ["ConfirmationRule", "CONFIRMATION", "advance", "advance_others",
           "first_confirmation", "leading"]


@dataclass(frozen=True)
class ConfirmationRule:
    #: consecutive classified flights the mode must lead
    flights: int = 2
    #: its pooled probability on the last of them, at least
    probability: float = 0.9
    #: consecutive classified flights a mode beside the leading one, named by its own feature
    #: beyond the leader's cross-talk, must stand in the set
    feature_flights: int = 6

    def __post_init__(self) -> None:
        if min(self.flights, self.feature_flights) < 1 or not 0.0 <= self.probability <= 1.0:
            raise ValueError("a confirmation needs at least one flight and a probability "
                             "in [0, 1]")


#: the rule the service runs (docs/TUNING.md: the leading mode's first cut, the feature path's
#: run length chosen on a concurrent design)
CONFIRMATION = ConfirmationRule()


def leading(probs: Mapping[str, float]) -> str:
    """The leading mode of one flight's probabilities (ties: the first in order)."""
    return max(probs, key=lambda c: probs[c])


def advance(rule: ConfirmationRule, lead: str | None, run: int,
            probs: Mapping[str, float]) -> tuple[str, int, bool]:
    """One classified flight: ``(leading mode, flights it has led in a row, whether the rule
    holds now)``, from the previous flight's ``lead`` and ``run``."""
    mode = leading(probs)
    run = run + 1 if mode == lead else 1
    return mode, run, run >= rule.flights and probs[mode] >= rule.probability


def advance_others(rule: ConfirmationRule, runs: Mapping[str, int], modes: Sequence[str],
                   own: Mapping[str, float], beyond: Collection[str] = ()
                   ) -> tuple[dict[str, int], list[str]]:
    """One classified flight for the modes beside the leading one (``modes[1:]``): each one's
    run of consecutive flights in the set (a mode that left it starts again), and those for
    which the rule holds now (``beyond``: the modes whose own feature is beyond the leading
    mode's cross-talk on this flight)."""
    new = {m: runs.get(m, 0) + 1 for m in modes[1:]}
    return new, [m for m, n in new.items()
                 if (n >= rule.flights and own.get(m, 0.0) >= rule.probability)
                 or (n >= rule.feature_flights and m in beyond)]


def first_confirmation(rule: ConfirmationRule,
                       sequence: Sequence[Mapping[str, float] | None]
                       ) -> tuple[int, str] | None:
    """The position in ``sequence`` (one flight's probabilities each, from the alarm on; None
    where a flight was not classified, which breaks a run) and the mode of the first
    confirmation; None if the rule never holds."""
    lead: str | None = None
    run = 0
    for i, probs in enumerate(sequence):
        if not probs:
            lead, run = None, 0
            continue
        lead, run, held = advance(rule, lead, run, probs)
        if held:
            return i, lead
    return None
