"""The design's cross-talk limits (server.phm.classification.crosstalk): pooled as the chain
pools, fitted per leading mode from its single faults' rows, and a second mode named beyond
them in the chain."""

from __future__ import annotations

import json

import numpy as np
import pytest

from server.phm.classification.crosstalk import MIN_ROWS, CrossTalk, fit_crosstalk, pooled_means
from server.vocabulary import GENERIC_FEATURES, OWN_FEATURE

DMD = list(GENERIC_FEATURES).index(OWN_FEATURE["DMD"])
TTS = list(GENERIC_FEATURES).index(OWN_FEATURE["TTS"])


def test_pooled_means_restart_per_group_and_follow_the_chains_recursion() -> None:
    rng = np.random.default_rng(0)
    X = rng.normal(size=(9, 3))
    groups = ["a"] * 4 + ["b"] * 5
    got = pooled_means(X, groups, decay=0.7)
    for start, stop in ((0, 4), (4, 9)):
        s = w = 0.0
        for k in range(start, stop):
            s, w = 0.7 * s + X[k], 0.7 * w + 1.0
            np.testing.assert_allclose(got[k], s / w)
    assert pooled_means(np.empty((0, 3)), [], decay=0.7).shape == (0, 3)


def _rows(n_per_pattern: int, patterns: int, lift: float, mode: str, seed: int
          ) -> tuple[np.ndarray, list[str], list[str]]:
    """Single faults of ``mode`` whose own feature grows and lifts F_DMD by ``lift`` times."""
    rng = np.random.default_rng(seed)
    X = rng.normal(scale=0.3, size=(n_per_pattern * patterns, len(GENERIC_FEATURES)))
    own = np.tile(np.linspace(1.0, 5.0, n_per_pattern), patterns)
    X[:, list(GENERIC_FEATURES).index(OWN_FEATURE[mode])] += own
    X[:, DMD] += lift * own
    groups = [f"{mode}{k // n_per_pattern}" for k in range(len(X))]
    return X, [mode] * len(X), groups


def test_the_limit_is_the_quantile_of_the_leaders_cross_talk_and_a_thin_mode_gets_none() -> None:
    Xt, yt, gt = _rows(20, 5, 0.5, "TTS", 1)
    Xm, ym, gm = _rows(10, 2, 0.0, "MTEL", 2)  # 20 rows: too few for a high quantile
    X, y, g = np.vstack([Xt, Xm]), yt + ym, gt + gm
    ct = fit_crosstalk(X, y, g, decay=0.7, quantile=0.99)
    pooled = pooled_means(X, g, 0.7)[: len(yt)]
    assert ct.limits["TTS"]["DMD"] == pytest.approx(np.quantile(pooled[:, DMD], 0.99))
    assert "MTEL" not in ct.limits and len(ym) < MIN_ROWS
    assert set(ct.limits["TTS"]) == {"DMD", "MTEL", "MTWEAR", "REWEAR"}
    # a DMD beyond what TTS alone gave it is named; at the cross-talk, or NaN, it is not
    top = ct.limits["TTS"]["DMD"]
    assert ct.beyond("TTS", {"DMD": top + 0.1, "MTEL": -1.0}) == ["DMD"]
    assert ct.beyond("TTS", {"DMD": top, "MTEL": float("nan")}) == []
    assert ct.beyond("MTEL", {"DMD": 99.0}) == []  # no limits for that leader: nothing named
    assert CrossTalk.from_dict(json.loads(json.dumps(ct.to_dict()))) == ct
    with pytest.raises(ValueError, match="quantile"):
        CrossTalk.from_dict({"quantile": 0.0, "limits": {}})
