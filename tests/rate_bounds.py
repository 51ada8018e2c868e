"""What a banked filter's rate bounds must admit (the training tests and the shipped model's)."""

from __future__ import annotations

from server.phm.prognosis import PrognoserConfig


def assert_bounds_admit_the_bank(cfg: PrognoserConfig, where: str) -> None:
    """The filter's mid-life rate bounds admit every band's mean rate and the fastest band's
    out to two standard deviations: a bound inside a band clips its faults' rates in
    propagation and prediction (their RUL too long where the bound is the upper one)."""
    assert cfg.rate_bounds is not None, where
    lo, hi = cfg.rate_bounds
    scale = abs(0.5 + cfg.growth_offset)
    for h in cfg.rate_hypotheses:
        assert lo <= abs(h.rate) * scale <= hi, (where, h.name, lo, hi)
    fastest = cfg.rate_hypotheses[0]
    assert (abs(fastest.rate) + 2 * fastest.rate_std) * scale <= hi, (where, hi)
