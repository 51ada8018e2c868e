"""The design's cross-talk limits (server.phm.classification.crosstalk): fitted per leading
mode from its single faults' rows between modes sharing a signal path, and a second mode named
beyond them."""

from __future__ import annotations

import json

import numpy as np
import pytest

from server.phm.classification.crosstalk import MIN_ROWS, CrossTalk, fit_crosstalk
from server.vocabulary import GENERIC_FEATURES, OWN_FEATURE

DMD = list(GENERIC_FEATURES).index(OWN_FEATURE["DMD"])


def _rows(n: int, lift: float, mode: str, seed: int) -> tuple[np.ndarray, list[str]]:
    """Flights in alarm of single faults of ``mode`` whose own feature grows and lifts F_DMD
    by ``lift`` times as much."""
    rng = np.random.default_rng(seed)
    X = rng.normal(scale=0.3, size=(n, len(GENERIC_FEATURES)))
    own = np.linspace(1.0, 5.0, n)
    X[:, list(GENERIC_FEATURES).index(OWN_FEATURE[mode])] += own
    X[:, DMD] += lift * own
    return X, [mode] * n


def test_the_limit_is_the_quantile_of_the_leaders_cross_talk_on_a_shared_signal_path() -> None:
    Xt, yt = _rows(100, 0.5, "TTS", 1)
    Xd, yd = _rows(80, 0.0, "DMD", 3)
    Xm, ym = _rows(20, 0.0, "MTEL", 2)  # too few rows for a high quantile
    Xt[0, DMD] = np.nan  # a feature set aside on a flight says nothing
    ct = fit_crosstalk(np.vstack([Xt, Xd, Xm]), yt + yd + ym, quantile=0.99)
    assert ct.limits["TTS"]["DMD"] == pytest.approx(np.nanquantile(Xt[:, DMD], 0.99))
    # the signal-path pairs only, both ways: TTS <-> DMD here; MTEL too thin for its limits
    assert ct.limits == {"TTS": {"DMD": ct.limits["TTS"]["DMD"]},
                         "DMD": {"TTS": ct.limits["DMD"]["TTS"]}}
    assert len(ym) < MIN_ROWS
    top = ct.limits["TTS"]["DMD"]
    assert ct.beyond("TTS", {"DMD": top + 0.1, "MTEL": 99.0}) == ["DMD"]
    assert ct.beyond("TTS", {"DMD": top}) == []
    assert ct.beyond("TTS", {"DMD": float("nan")}) == []
    assert ct.beyond("MTEL", {"DMD": 99.0}) == []  # no limits for that leader: nothing named
    every = fit_crosstalk(np.vstack([Xt, Xd]), yt + yd, pairs=[("TTS", "DMD")])
    assert every.limits["TTS"]["DMD"] == pytest.approx(np.nanmax(Xt[:, DMD]))  # default: max
    assert CrossTalk.from_dict(json.loads(json.dumps(ct.to_dict()))) == ct
    with pytest.raises(ValueError, match="quantile"):
        CrossTalk.from_dict({"quantile": 0.0, "limits": {}})
