"""The design's cross-talk limits (server.phm.classification.crosstalk): fitted per leading
mode from its single faults' rows between modes sharing a signal path, following the leading
mode's own feature, and a second mode named beyond them."""

from __future__ import annotations

import json

import numpy as np
import pytest

from server.phm.classification.crosstalk import MIN_ROWS, CrossTalk, CrossTalkLimit, fit_crosstalk
from server.vocabulary import GENERIC_FEATURES, OWN_FEATURE

COL = {m: list(GENERIC_FEATURES).index(f) for m, f in OWN_FEATURE.items()}


def _rows(n: int, lift: float, mode: str, seed: int) -> tuple[np.ndarray, list[str]]:
    """Flights in alarm of single faults of ``mode`` whose own feature grows and lifts F_DMD
    by ``lift`` times as much."""
    rng = np.random.default_rng(seed)
    X = rng.normal(scale=0.3, size=(n, len(GENERIC_FEATURES)))
    own = np.linspace(1.0, 5.0, n)
    X[:, COL[mode]] += own
    X[:, COL["DMD"]] += lift * own
    return X, [mode] * n


def test_the_limit_follows_the_leaders_own_feature_on_a_shared_signal_path() -> None:
    Xt, yt = _rows(100, 0.5, "TTS", 1)
    Xd, yd = _rows(80, 0.0, "DMD", 3)
    Xm, ym = _rows(20, 0.0, "MTEL", 2)  # too few rows for a high quantile
    Xt[0, COL["DMD"]] = np.nan  # a feature set aside on a flight says nothing
    ct = fit_crosstalk(np.vstack([Xt, Xd, Xm]), yt + yd + ym, quantile=0.99)
    # the signal-path pairs only, both ways: TTS <-> DMD here; MTEL too thin for its limits
    assert set(ct.limits) == {"TTS", "DMD"} and set(ct.limits["TTS"]) == {"DMD"}
    assert set(ct.limits["DMD"]) == {"TTS"}
    assert len(ym) < MIN_ROWS
    lim = ct.limits["TTS"]["DMD"]
    x, v = Xt[1:, COL["TTS"]], Xt[1:, COL["DMD"]]
    slope, _ = np.polyfit(x, v, 1)
    assert lim.slope == pytest.approx(slope) and 0.35 < lim.slope < 0.65  # the lift, 0.5
    assert lim.at == pytest.approx(np.quantile(v - slope * x, 0.99))
    assert lim.floor == pytest.approx(np.quantile(v[x <= np.median(x)], 0.99))
    assert np.mean(v > [lim.of(t) for t in x]) <= 0.02  # 1 % above the line, or fewer
    # a DMD-sized feature beside a moderate short is beyond the limit, beside a strong one not
    mid = lim.of(3.5)
    assert mid > lim.floor
    assert ct.beyond("TTS", {"TTS": 3.5, "DMD": mid + 0.1, "MTEL": 99.0}) == ["DMD"]
    assert ct.beyond("TTS", {"TTS": 5.0, "DMD": mid + 0.1}) == []
    # below the design's milder half the line would fall into the healthy scatter: the floor
    assert lim.of(-10.0) == lim.floor
    assert ct.beyond("TTS", {"TTS": -10.0, "DMD": lim.floor}) == []
    assert ct.beyond("TTS", {"TTS": 1.0, "DMD": float("nan")}) == []
    assert ct.beyond("TTS", {"DMD": 99.0}) == []  # the leader's feature unknown: no limit
    assert ct.beyond("MTEL", {"DMD": 99.0}) == []  # no limits for that leader: nothing named
    # DMD alone does not lift F_TTS: its slope is clipped at 0, one limit at any severity
    assert ct.limits["DMD"]["TTS"].slope == 0.0
    assert CrossTalk.from_dict(json.loads(json.dumps(ct.to_dict()))) == ct


def test_flat_limits_are_the_quantile_and_documents_of_them_still_read() -> None:
    Xt, yt = _rows(100, 0.5, "TTS", 1)
    flat = fit_crosstalk(Xt, yt, pairs=[("TTS", "DMD")], conditional=False)
    assert flat.limits["TTS"]["DMD"] == CrossTalkLimit(float(np.max(Xt[:, COL["DMD"]])))
    assert flat.beyond("TTS", {"DMD": 99.0}) == ["DMD"]  # needs no leader's feature
    older = {"quantile": 1.0, "limits": {"TTS": {"DMD": 2.5}}}  # a number per pair
    assert CrossTalk.from_dict(older).limits["TTS"]["DMD"] == CrossTalkLimit(2.5, 0.0)
    assert CrossTalkLimit(2.5).to_dict() == {"at": 2.5, "slope": 0.0}  # no floor: none written
    with pytest.raises(ValueError, match="quantile"):
        CrossTalk.from_dict({"quantile": 0.0, "limits": {}})
    for bad in ({"at": 1.0, "slope": -0.1}, {"at": float("nan")}, float("inf"),
                {"at": 1.0, "slope": 0.5, "floor": float("nan")}):
        with pytest.raises(ValueError, match="slope non-negative"):
            CrossTalk.from_dict({"quantile": 1.0, "limits": {"TTS": {"DMD": bad}}})
