"""A calibration layer for the RUL bands: group-conditional (Mondrian) conformalized quantile
regression in log(1 + RUL), each end of a band on its own.

The filter's 50 % and 90 % bands are the particles' central quantiles; whether they hold the
truth that often depends on how well the design prior and the degradation law fit the fault.
The layer corrects each band by a margin learned on replays of design runs kept for
calibration only (Romano, Patterson and Candes, "Conformalized quantile regression", NeurIPS
2019, its asymmetric form; Vovk's Mondrian conformal prediction for the groups). For a
prediction with band [lo, hi] and true RUL y the two conformity scores are::

    E_lo = log(1 + lo) - log(1 + y)        E_hi = log(1 + y) - log(1 + hi)

(negative when the truth lies inside). Each end's margin Q is the ceil((n + 1)(1 - a/2))-th
smallest of its group's n scores (a = 0.5 or 0.1, the band's miss rate), and the band becomes
[(1 + lo) e^-Q_lo - 1, (1 + hi) e^Q_hi - 1]: an optimistic filter's lower end moves down
without widening its upper end, a too cautious one's ends move in. The median moves by the
median of its group's log errors, log(1 + y) - log(1 + median): the point estimate of a
filter that is systematically optimistic in a group is corrected there too.

Groups use only what is known when the prediction is made: the fault mode, and either the
leading hypothesis of a bank of rate hypotheses (:mod:`.hypotheses`; ``RulDistribution.
hypothesis``), or the filter's rate relative to the design prior
(``RulDistribution.rate_ratio``) binned at ``edges``: a fault faster than the design runs is
miscalibrated differently from one in range. With ``weight_split`` each leading hypothesis's
group is split again by the leader's weight: a lead below it (an ambiguous lead, where the
lower ends miss most often: a fast life still led by a slower band) gets margins of its own,
apart from the confident lead's. A group with fewer than ``min_group`` scores uses the next
coarser one's margins: a split group its hypothesis's, a hypothesis's the mode's pooled.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from .predictor import RulDistribution

__all__ = ["BAND_LEVELS", "DEFAULT_WEIGHT_SPLIT", "BandCalibration", "CalibrationRecord",
           "fit_band_calibration", "widen"]

_FORMAT = "rul-band-calibration/2"
#: per band coverage, the margins (Q_lo, Q_hi) of its lower and upper end [log(1 + RUL)]
Margins = dict[float, tuple[float, float]]
#: the central bands the layer calibrates: coverage -> (lower level, upper level)
BAND_LEVELS = {0.5: (0.25, 0.75), 0.9: (0.05, 0.95)}
#: [-] the leader's weight below which ``hmsm calibrate`` calibrates a lead apart (the
#: dashboard's "fast fault, 0.8", not tuned; the split itself chosen on design seeds 7 and 8,
#: docs/TUNING.md)
DEFAULT_WEIGHT_SPLIT = 0.8


@dataclass(frozen=True)
class CalibrationRecord:
    """One replayed prediction: its band quantiles {level: RUL}, the filter's rate ratio, the
    true RUL [flights], the leading rate hypothesis (None without a bank) and its weight."""

    quantiles: Mapping[float, float]
    rate_ratio: float
    true_rul: float
    hypothesis: str | None = None
    weight: float = 1.0


@dataclass(frozen=True)
class BandCalibration:
    """The layer of one fault mode: its groups (the rate hypotheses by name when
    ``hypotheses`` is set, else the rate-ratio bins of ``edges``, ascending), each group's
    margins {coverage: (Q_lo, Q_hi)} (log units) and size, and the pooled margins; with
    ``weight_split``, each hypothesis's ambiguous and confident lead's margins, sizes and
    shifts too (``split_*``, two per hypothesis: ambiguous first)."""

    edges: tuple[float, ...]
    margins: tuple[Margins, ...]
    counts: tuple[int, ...]
    pooled: Margins
    #: each group's and the pooled shift of the median [log(1 + RUL)]
    shifts: tuple[float, ...] = ()
    pooled_shift: float = 0.0
    min_group: int = 30
    n_records: int = 0
    n_runs: int = 0
    notes: dict[str, Any] = field(default_factory=dict)
    hypotheses: tuple[str, ...] = ()
    #: [-] the leader's weight below which a lead is ambiguous (None: no split)
    weight_split: float | None = None
    split_margins: tuple[Margins, ...] = ()
    split_counts: tuple[int, ...] = ()
    split_shifts: tuple[float, ...] = ()

    @property
    def n_groups(self) -> int:
        return len(self.hypotheses) if self.hypotheses else len(self.edges) + 1

    def group_of(self, rate_ratio: float, hypothesis: str | None = None) -> int:
        """The group of a prediction (-1: none, the pooled margins)."""
        if self.hypotheses:
            return self.hypotheses.index(hypothesis) if hypothesis in self.hypotheses else -1
        if not math.isfinite(rate_ratio):
            return -1
        return int(np.searchsorted(np.asarray(self.edges), rate_ratio, side="right"))

    def split_of(self, group: int, weight: float) -> int:
        """The split group of a prediction in hypothesis group ``group`` led with ``weight``
        (-1: no split)."""
        if self.weight_split is None or group < 0 or not self.hypotheses:
            return -1
        return 2 * group + int(weight >= self.weight_split)

    def margins_for(self, rate_ratio: float, hypothesis: str | None = None,
                    weight: float = 1.0) -> tuple[int, Margins, float]:
        """(group, margins, median shift) of a prediction; group -1 is the pooled fallback."""
        group, _, margins, shift = self._chosen(rate_ratio, hypothesis, weight)
        return group, margins, shift

    def _chosen(self, rate_ratio: float, hypothesis: str | None, weight: float
                ) -> tuple[int, str | None, Margins, float]:
        """(group, the lead's half when a split group's own margins apply, margins, shift)."""
        g = self.group_of(rate_ratio, hypothesis)
        if g < 0 or self.counts[g] < self.min_group:
            return -1, None, self.pooled, self.pooled_shift
        s = self.split_of(g, weight)
        if s >= 0 and self.split_counts[s] >= self.min_group:
            return (g, "confident" if s % 2 else "ambiguous", self.split_margins[s],
                    self.split_shifts[s])
        return g, None, self.margins[g], self.shifts[g]

    def apply(self, dist: RulDistribution) -> RulDistribution:
        group, lead, margins, shift = self._chosen(dist.rate_ratio, *_leading(dist))
        out = widen(dist, margins, median_shift=shift)
        adjustment = {**(dist.adjustment or {}), "conformal_group": group,
                      "conformal_margins": {c: list(m) for c, m in margins.items()},
                      "median_shift": shift}
        if lead is not None:
            adjustment["conformal_lead"] = lead
        return replace(out, adjustment=adjustment)

    def to_dict(self) -> dict[str, Any]:
        out = {"format": _FORMAT, "edges": list(self.edges),
               "margins": [_margins_out(m) for m in self.margins],
               "counts": list(self.counts), "pooled": _margins_out(self.pooled),
               "shifts": list(self.shifts), "pooled_shift": self.pooled_shift,
               "min_group": self.min_group, "n_records": self.n_records,
               "n_runs": self.n_runs, "notes": self.notes}
        if self.hypotheses:  # absent otherwise: documents read as before
            out["hypotheses"] = list(self.hypotheses)
        if self.weight_split is not None:
            out["weight_split"] = self.weight_split
            out["split_margins"] = [_margins_out(m) for m in self.split_margins]
            out["split_counts"] = list(self.split_counts)
            out["split_shifts"] = list(self.split_shifts)
        return out

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> BandCalibration:
        if d.get("format") != _FORMAT:
            raise ValueError(f"not a {_FORMAT} document")
        edges = tuple(float(e) for e in d["edges"])
        margins = tuple(_margins_in(m) for m in d["margins"])
        counts = tuple(int(c) for c in d["counts"])
        shifts = tuple(float(v) for v in d["shifts"])
        hypotheses = tuple(str(h) for h in d.get("hypotheses") or ())
        groups = len(hypotheses) if hypotheses else len(edges) + 1
        if list(edges) != sorted(edges) or len(margins) != groups \
                or len(counts) != len(margins) or len(shifts) != len(margins) \
                or not all(math.isfinite(v) for v in (*shifts, float(d["pooled_shift"]))):
            raise ValueError("band calibration: one group per hypothesis, or edges ascending "
                             "with one group more; each group with its margins and a finite "
                             "shift")
        layer = cls(edges, margins, counts, _margins_in(d["pooled"]), shifts,
                    float(d["pooled_shift"]), int(d["min_group"]), int(d.get("n_records", 0)),
                    int(d.get("n_runs", 0)), dict(d.get("notes") or {}), hypotheses)
        return layer if d.get("weight_split") is None else _with_split(layer, d)


def _with_split(layer: BandCalibration, d: Mapping[str, Any]) -> BandCalibration:
    """``layer`` with the split groups of its document ``d`` (two per hypothesis)."""
    split = float(d["weight_split"])
    margins = tuple(_margins_in(m) for m in d["split_margins"])
    counts = tuple(int(c) for c in d["split_counts"])
    shifts = tuple(float(v) for v in d["split_shifts"])
    if not layer.hypotheses or not 0.0 < split <= 1.0 \
            or not len(margins) == len(counts) == len(shifts) == 2 * len(layer.hypotheses) \
            or not all(math.isfinite(v) for v in shifts):
        raise ValueError("band calibration: a weight split in (0, 1] needs a bank, and two "
                         "groups per hypothesis, each with its margins and a finite shift")
    return replace(layer, weight_split=split, split_margins=margins, split_counts=counts,
                   split_shifts=shifts)


def _margins_out(m: Margins) -> list[list[float]]:
    return [[float(c), float(lo), float(hi)] for c, (lo, hi) in sorted(m.items())]


def _margins_in(rows: Sequence[Sequence[float]]) -> Margins:
    out = {float(c): (float(lo), float(hi)) for c, lo, hi in rows}
    if set(out) != set(BAND_LEVELS) or not all(math.isfinite(v) for m in out.values()
                                               for v in m):
        raise ValueError(f"band margins need finite values for coverages {sorted(BAND_LEVELS)}")
    return out


def _band_margins(records: Sequence[CalibrationRecord], coverage: float) -> tuple[float, float]:
    """(Q_lo, Q_hi) of one band: each end's conformal quantile at 1 - (1 - coverage) / 2."""
    lo_level, hi_level = BAND_LEVELS[coverage]
    y = np.log1p(np.array([r.true_rul for r in records], dtype=float))
    lo = np.log1p(np.array([r.quantiles[lo_level] for r in records], dtype=float))
    hi = np.log1p(np.array([r.quantiles[hi_level] for r in records], dtype=float))
    level = 1.0 - 0.5 * (1.0 - coverage)
    return _margin(lo - y, level), _margin(y - hi, level)  # an open band's end: -inf, inside


def _median_shift(records: Sequence[CalibrationRecord]) -> float:
    """The median of log(1 + y) - log(1 + median) (0 without a finite one)."""
    err = np.array([math.log1p(r.true_rul) - math.log1p(r.quantiles[0.5]) for r in records])
    err = err[np.isfinite(err)]
    return float(np.median(err)) if err.size else 0.0


def _margin(scores: np.ndarray, level: float) -> float:
    """The conformal quantile: the ceil((n + 1) level)-th smallest score (the largest if that
    rank passes n); 0 where it is not finite (an end open beyond the horizon)."""
    s = np.sort(scores)
    rank = min(int(math.ceil((s.size + 1) * level)), s.size)
    value = float(s[rank - 1])
    return value if math.isfinite(value) else 0.0


def fit_band_calibration(records: Iterable[CalibrationRecord], *,
                         edges: tuple[float, ...] = (0.5, 2.0), min_group: int = 30,
                         n_runs: int = 0, hypotheses: tuple[str, ...] = (),
                         weight_split: float | None = None) -> BandCalibration:
    """The layer of one mode from its replayed predictions (each band's quantiles finite
    below, the truth finite), grouped by leading hypothesis when ``hypotheses`` names a
    bank's (and split by the leader's weight at ``weight_split``), else by rate ratio at
    ``edges``."""
    recs = [r for r in records if math.isfinite(r.true_rul) and r.true_rul >= 0]
    if not recs:
        raise ValueError("no replayed prediction to calibrate on")
    edges = () if hypotheses else tuple(sorted(float(e) for e in edges))
    pooled = {c: _band_margins(recs, c) for c in BAND_LEVELS}
    layer = BandCalibration(edges, (), (), pooled, (), _median_shift(recs), min_group,
                            len(recs), n_runs, hypotheses=tuple(hypotheses))
    groups: list[list[CalibrationRecord]] = [[] for _ in range(layer.n_groups)]
    for r in recs:
        g = layer.group_of(r.rate_ratio, r.hypothesis)
        if g >= 0:
            groups[g].append(r)
    layer = replace(layer, **_groups_fitted(groups, pooled, layer.pooled_shift))
    if weight_split is None or not hypotheses:
        return layer
    if not 0.0 < weight_split <= 1.0:
        raise ValueError(f"weight_split must lie in (0, 1], got {weight_split!r}")
    halves: list[list[CalibrationRecord]] = [[] for _ in range(2 * layer.n_groups)]
    for g, members in enumerate(groups):
        for r in members:
            halves[2 * g + int(r.weight >= weight_split)].append(r)
    fitted = _groups_fitted(halves, pooled, layer.pooled_shift)
    return replace(layer, weight_split=float(weight_split), split_margins=fitted["margins"],
                   split_counts=fitted["counts"], split_shifts=fitted["shifts"])


def _groups_fitted(groups: Sequence[Sequence[CalibrationRecord]], pooled: Margins,
                   pooled_shift: float) -> dict[str, Any]:
    """Each group's margins, size and median shift (an empty group: the pooled)."""
    return {"margins": tuple({c: _band_margins(g, c) for c in BAND_LEVELS} if g
                             else dict(pooled) for g in groups),
            "counts": tuple(len(g) for g in groups),
            "shifts": tuple(_median_shift(g) if g else pooled_shift for g in groups)}


def _leading(dist: RulDistribution) -> tuple[str | None, float]:
    """The leading hypothesis's name and weight (None, 1 without a bank)."""
    if dist.hypothesis is None:
        return None, 1.0
    return dist.hypothesis.get("name"), float(dist.hypothesis.get("weight", 1.0))


def widen(dist: RulDistribution, margins: Margins, *, median_shift: float = 0.0
          ) -> RulDistribution:
    """``dist`` with each central band's ends moved out by their margins (Q_lo, Q_hi) in
    log(1 + RUL) (in, where negative), the median moved by ``median_shift`` in the same
    units, the quantiles kept in order around it; the probabilities of failure within the
    horizons are read off the new quantiles (linear between levels)."""
    q = dict(dist.quantiles)
    median = dist.median
    if median_shift and math.isfinite(median):
        median = math.expm1(math.log1p(median) + median_shift)
        q[0.5] = median
    for coverage, (lo_level, hi_level) in BAND_LEVELS.items():
        m_lo, m_hi = margins.get(coverage, (0.0, 0.0))
        if lo_level in q:
            q[lo_level] = min(math.expm1(math.log1p(q[lo_level]) - m_lo), median)
        if hi_level in q and math.isfinite(q[hi_level]):
            q[hi_level] = max(math.expm1(math.log1p(q[hi_level]) + m_hi), median)
    below = sorted((lv for lv in q if lv < 0.5), reverse=True)  # inner to outer
    above = sorted(lv for lv in q if lv > 0.5)
    for inner, outer in zip(below, below[1:], strict=False):
        q[outer] = min(q[outer], q[inner])
    for inner, outer in zip(above, above[1:], strict=False):
        q[outer] = max(q[outer], q[inner])
    q = {lv: max(v, 0.0) for lv, v in q.items()}
    return replace(dist, quantiles=q, p_fail_within=_pof_from_quantiles(q, dist))


def _pof_from_quantiles(q: Mapping[float, float], dist: RulDistribution) -> dict[int, float]:
    """P(RUL <= k) by linear interpolation of the quantile function's inverse through
    (0, 0) and the finite quantiles; beyond the last finite one, the particles' value."""
    pts = sorted((v, lv) for lv, v in q.items() if math.isfinite(v))
    xs = np.array([0.0] + [v for v, _ in pts])
    ps = np.array([0.0] + [lv for _, lv in pts])
    xs = np.maximum.accumulate(xs)
    out = {}
    for k, raw in dist.p_fail_within.items():
        if pts and k <= xs[-1]:
            out[k] = float(np.interp(k, xs, ps))
        else:
            out[k] = max(float(raw), float(ps[-1]))
    return out
