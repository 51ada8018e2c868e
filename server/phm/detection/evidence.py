"""A flight's scatter follows its recording: the sampling share of each feature's scatter.

A feature averages its flight's valid windows (steps, events, cruise time), so the part of its
flight-to-flight scatter that is sampling noise falls as ``1 / n_valid``: a 60 s recording's
residual scatters more than a 300 s one's. With ``w`` the flight's evidence weight (the design
flights' median ``n_valid`` over this flight's, ``FleetBaseline.evidence_weights``) the flight
noise is modelled as ``e ~ N(0, sigma^2 (1 - a) + sigma^2 a w)``, ``a`` the sampling share of
the scatter at typical evidence, learned per generic feature on the healthy design flights
(:func:`evidence_shares`). A flight then gets the extra variance ``sigma^2 a (w - 1)``
(negative for a recording longer than typical: a tighter test); the bands are learned on
statistics standardised the same way, so one model serves recordings of any length and a fleet
that mixes them. ``a`` is at most ``MAX_EVIDENCE_SHARE``; a design of one recording length (too
narrow a spread of ``w`` to regress on) learns ``a = 0``, the constant scatter.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence

import numpy as np

__all__ = ["MAX_EVIDENCE_SHARE", "MIN_EVIDENCE_SPREAD", "at_typical_evidence",
           "evidence_shares"]

#: largest sampling share ``a`` of a feature's flight scatter: some scatter is never sampling
#: noise (conditions the covariates miss), so a very long recording keeps a band of its own
MAX_EVIDENCE_SHARE = 0.95
#: the evidence weights of a design must spread by this factor (90th over 10th percentile)
#: to regress the scatter on them; below it ``a = 0``
MIN_EVIDENCE_SPREAD = 1.5
_EVIDENCE_BINS = 8


def evidence_shares(healthy_sequences: Sequence[np.ndarray],
                    evidence: Sequence[np.ndarray], groups: Sequence[Sequence[int]]
                    ) -> np.ndarray:
    """The sampling share ``a`` of each column's flight scatter, one per group of columns (a
    generic feature's positions): the robust variance (1.4826 MAD, squared) of the deviations
    from each history's median, in ``_EVIDENCE_BINS`` bins of the evidence weight ``w``,
    fitted as ``c0 + c1 w``; ``a = c1 / (c0 + c1)`` in ``[0, MAX_EVIDENCE_SHARE]``, 0 where
    ``w`` spreads too little to tell."""
    n_feat = np.asarray(healthy_sequences[0]).shape[1]
    share = np.zeros(n_feat)
    for idx in groups:
        dev, wts = [], []
        for q, e in zip(healthy_sequences, evidence, strict=True):
            for j in idx:
                col, w = np.asarray(q)[:, j], np.asarray(e)[:, j]
                ok = np.isfinite(col) & np.isfinite(w) & (w > 0)
                if ok.sum() >= 2:
                    dev.append(col[ok] - np.median(col[ok]))
                    wts.append(w[ok])
        if not dev:
            continue
        d, w = np.concatenate(dev), np.concatenate(wts)
        lo, hi = np.quantile(w, [0.1, 0.9])
        if d.size < 20 * _EVIDENCE_BINS or not hi >= MIN_EVIDENCE_SPREAD * lo:
            continue
        edges = np.quantile(w, np.linspace(0.0, 1.0, _EVIDENCE_BINS + 1))
        which = np.clip(np.searchsorted(edges, w, side="right") - 1, 0, _EVIDENCE_BINS - 1)
        wb, vb, nb = [], [], []
        for b in range(_EVIDENCE_BINS):
            sel = which == b
            if sel.sum() >= 10:
                wb.append(float(np.mean(w[sel])))
                vb.append((1.4826 * float(np.median(np.abs(d[sel])))) ** 2)
                nb.append(float(sel.sum()))
        if len(wb) < 3:
            continue
        c1, c0 = np.polyfit(np.array(wb), np.array(vb), 1, w=np.sqrt(np.array(nb)))
        total = c0 + c1
        if total > 0:
            share[list(idx)] = min(max(c1 / total, 0.0), MAX_EVIDENCE_SHARE)
    return share


def at_typical_evidence(q: np.ndarray, w: np.ndarray, share: np.ndarray) -> np.ndarray:
    """A history's residuals with each flight's deviation from the history's median brought
    to typical evidence: divided by ``sqrt(1 - a + a w)``, its scatter's ratio to ``sigma``."""
    factor = np.sqrt(1.0 - share + share * np.where(np.isfinite(w), w, 1.0))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # a column without a value stays NaN
        med = np.nanmedian(q, axis=0, keepdims=True)
    return med + (q - med) / factor
