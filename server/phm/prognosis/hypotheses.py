"""The fault's speed as hypotheses the measurements weigh: a bank of rate priors, one per band
of fault-to-failure spans.

A test station may ask for a fault that fails in 30 flights or in 1,000. One normal prior on
the exponential law's rate r over that whole range is either wide (blurring the bands of the
faults in range) or narrow (losing the fast ones). The bank splits the envelope into bands of
spans (for example 30-100, 100-300 and 300-1000 flights); each band is a hypothesis with a
rate prior N(r_k, s_k^2) and a prior weight w0_k. Every band's
RLS runs on the same measurements and its weight follows the band's evidence for them, or its
RLS's predictive likelihood (``PrognoserConfig.rate_weighting``, :mod:`.mixture`); the RUL
distribution is the weighted mixture, and the leading hypothesis
with its weight is what an engineer reads beside the band ("fast fault, 0.8").

Each band's prior comes from every design run, not only those inside it: a run's rate times
its span, rho = r x span, is about the same for every run of a mode (for dh/dk = r (h + c) from
the onset severity h0 to the threshold 1, rho = ln((1 + c) / (h0 + c))), so a design with a few
runs per band still informs each band. With the span log-uniform over the band [a, b] and rho
independent of it, r = rho / span has the moments::

    E[r]   = E[rho]   (1/a - 1/b) / ln(b/a)
    E[r^2] = E[rho^2] (1/a^2 - 1/b^2) / (2 ln(b/a))

the band's prior the normal with that mean and standard deviation (times ``inflation``). A
mode aging on a stress clock (:mod:`server.phm.season`) has its rates per stress unit; rho is
then taken per flight of span all the same (a base's stress per flight varies by season, not
by band).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["RateHypothesis", "band_names", "fit_rate_hypotheses", "leading_hypothesis"]

#: the bands' names by their number, fastest first
_NAMES = {1: ("in range",), 2: ("fast", "slow"), 3: ("fast", "medium", "slow"),
          4: ("very fast", "fast", "medium", "slow"),
          5: ("very fast", "fast", "medium", "slow", "very slow")}


@dataclass(frozen=True)
class RateHypothesis:
    """One band of fault-to-failure spans: its name, its spans [flights], the exponential
    law's rate prior (mean, standard deviation) [1/clock unit] and its prior weight [-]."""

    name: str
    low_flights: float
    high_flights: float
    rate: float
    rate_std: float
    weight: float

    def __post_init__(self) -> None:
        if not self.name or not isinstance(self.name, str):
            raise ValueError("a rate hypothesis needs a name")
        lo, hi = float(self.low_flights), float(self.high_flights)
        if not (math.isfinite(hi) and lo > 0.0 and hi > lo):
            raise ValueError(f"rate hypothesis {self.name!r}: spans need 0 < low < high < inf, "
                             f"got {self.low_flights!r}, {self.high_flights!r}")
        for field_name in ("rate", "rate_std", "weight"):
            if not math.isfinite(float(getattr(self, field_name))):
                raise ValueError(f"rate hypothesis {self.name!r}: {field_name} must be finite")
        if self.rate == 0.0 or self.rate_std <= 0.0 or self.weight <= 0.0:
            raise ValueError(f"rate hypothesis {self.name!r}: rate must be non-zero, rate_std "
                             "and weight > 0")
        for field_name in ("low_flights", "high_flights", "rate", "rate_std", "weight"):
            object.__setattr__(self, field_name, float(getattr(self, field_name)))

    @property
    def spans(self) -> str:
        """The band in words, e.g. ``30-100 flights``."""
        return f"{self.low_flights:g}-{self.high_flights:g} flights"

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "low_flights": self.low_flights,
                "high_flights": self.high_flights,
                "rate": self.rate, "rate_std": self.rate_std, "weight": self.weight}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> RateHypothesis:
        return cls(str(data["name"]), float(data["low_flights"]),
                   float(data["high_flights"]), float(data["rate"]),
                   float(data["rate_std"]), float(data["weight"]))


def band_names(edges: Sequence[float]) -> tuple[tuple[str, float, float], ...]:
    """The bands ``(name, low, high)`` [flights] between ascending ``edges`` (none for no
    edges); ValueError for edges that are not 2 to 6 ascending positive finite values."""
    e = [float(v) for v in edges]
    if not e:
        return ()
    if not (2 <= len(e) <= 6 and all(math.isfinite(v) and v > 0 for v in e)
            and all(a < b for a, b in zip(e, e[1:], strict=False))):
        raise ValueError(f"rate band edges must be 2 to 6 ascending positive spans, got {e}")
    names = _NAMES[len(e) - 1]
    return tuple((n, a, b) for n, a, b in zip(names, e, e[1:], strict=False))


def fit_rate_hypotheses(rates: Sequence[float], spans: Sequence[float],
                        bands: Sequence[tuple[str, float, float]], *, inflation: float = 1.0
                        ) -> tuple[RateHypothesis, ...]:
    """One hypothesis per band ``(name, low, high)`` [flights] from the design runs' fitted
    rates and spans [flights] (the module's moments of rho / span), equal prior weights."""
    r = np.asarray(rates, dtype=float)
    s = np.asarray(spans, dtype=float)
    if r.shape != s.shape or r.size < 2 or not (np.all(np.isfinite(r)) and np.all(s > 0)):
        raise ValueError("rate hypotheses need at least two runs with finite rates and spans")
    rho = r * s
    m1, m2 = float(rho.mean()), float((rho**2).mean())
    out = []
    for name, low, high in bands:
        a, b = float(low), float(high)
        if not (0.0 < a < b < math.inf):
            raise ValueError(f"band {name!r} needs 0 < low < high < inf, got {low}, {high}")
        log_ratio = math.log(b / a)
        mean = m1 * (1.0 / a - 1.0 / b) / log_ratio
        second = m2 * (1.0 / a**2 - 1.0 / b**2) / (2.0 * log_ratio)
        std = inflation * math.sqrt(max(second - mean**2, 0.0))
        out.append(RateHypothesis(name, a, b, mean, max(std, 0.05 * abs(mean)),
                                  1.0 / len(bands)))
    return tuple(out)


def leading_hypothesis(hypotheses: Sequence[RateHypothesis], weights: NDArray[np.float64]
                       ) -> dict[str, Any]:
    """The most probable hypothesis: its name, spans in words and weight, and every
    hypothesis's weight by name (what the RUL distribution carries)."""
    if len(hypotheses) != weights.size:
        raise ValueError("one weight per hypothesis needed")
    k = int(np.argmax(weights))
    return {"name": hypotheses[k].name, "spans": hypotheses[k].spans,
            "weight": float(weights[k]),
            "weights": {h.name: float(w) for h, w in zip(hypotheses, weights, strict=True)}}
