"""Fixed constants of the prognosis engine: the same for every fault mode and every model.

They are not hyper-parameters of one prognoser (those are the fields of
:class:`~server.phm.prognosis.PrognoserConfig`, which a model document stores), so they are not
serialised: changing one changes the engine, not a model. Their values and how they were chosen:
docs/TUNING.md, "Prognosis".
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["CONSTANTS", "PrognosisConstants"]


@dataclass(frozen=True)
class PrognosisConstants:
    """Constants of :mod:`server.phm.prognosis` (units in brackets).

    Attributes
    ----------
    rate_prior_spread:
        Prior standard deviation of the exponential law's rate r when the config gives none,
        as a fraction of the first-trial |r| [-]: degradation patterns of one mode differ in
        rate by about 35 % (fault-to-failure spans of U(170, 360) flights).
    min_level_gap:
        Smallest |h + c| of the log-level observation of a saturating law (c < -1) [-]: keeps
        ln|h + c| finite for an estimate at or past the asymptote.
    mode_grid:
        Bins of the binned kernel density behind the most probable RUL [-]: one small
        convolution instead of N x grid exponentials (0.08 ms per prediction).
    inversion_grid:
        Points of the severity -> feature table that inverts a measurement model [-]: a
        severity step of 1.5 / 512 = 0.003 on the default range [0, 1.5].
    min_growth_points:
        Fewest measurements of the growing part of a change-point fit [-]: a line through two
        points is exact, so it needs three to have a residual.
    short_series_noise:
        Noise standard deviation the generic interface assumes for a series too short
        (< 4 samples) to estimate it [severity, threshold distance = 1]: a fallback, not fitted.
    rate_tail_factors:
        Multiples of the prior rate at which the exponential law's rate prior puts its tail
        components (``PrognoserConfig.rate_prior_tail``) [-]: steps of 1.5 from 3 times slower
        to 6.75 times faster than the design median, so that a fault with a life of 50 flights
        (5 times faster than the design's median of about 260) or of 800 (3 times slower)
        lies within one prior standard deviation of a component.
    """

    rate_prior_spread: float = 0.35
    min_level_gap: float = 0.02
    mode_grid: int = 256
    inversion_grid: int = 513
    min_growth_points: int = 3
    short_series_noise: float = 0.05
    rate_tail_factors: tuple[float, ...] = (1.0 / 3.0, 0.5, 2.0, 3.0, 4.5, 6.75)


#: the engine's constants (one instance; every module reads its values from here)
CONSTANTS = PrognosisConstants()
