"""The online judge (``update_units``) and its vectorised form over flight sequences
(``server.phm.detection.sequences``) say the same on the same flights: confidences, the
evidence the winglet pair's rule leaves to the partner, the alarms, the healthy statistics the
bands are learned on and the healthy alarm rate."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.special import ndtri

from server.phm.detection import (
    DetectionResult,
    FaultDetector,
    first_alarms,
    healthy_statistics,
    judge_sequence,
    new_states,
    update_units,
)
from server.phm.detection_model import healthy_alarm_rate
from server.phm.features import AIRCRAFT_FEATURES

NAMES = ["WL1.F_MTEL", "WL1.F_DMD", "WL2.F_MTEL", "WL2.F_DMD", "WT.F_MTEL", "WT.F_SE"]
UNITS = ("WL1", "WL2", "WT")
WEIGHTS = (0.2, 0.5, 1.0, 1.0, 2.0)


def _aircraft(rng: np.random.Generator, n: int, names: list[str] = NAMES) -> np.ndarray:
    """Healthy residuals of one aircraft: each actuator's own offset, and each winglet drive's
    friction ratio only on the flights it is the active one (the standby's is NaN)."""
    z = rng.standard_normal((n, len(names))) + rng.normal(0.0, 0.5, len(names))
    for j, name in enumerate(names):
        if name == "WL1.F_MTEL":
            z[1::2, j] = np.nan
        elif name == "WL2.F_MTEL":
            z[0::2, j] = np.nan
    return z


def _fitted(rng: np.random.Generator, names: list[str] = NAMES, **kw: object) -> FaultDetector:
    seqs = [_aircraft(rng, 120, names) for _ in range(8)]
    weights = [rng.choice(WEIGHTS, size=q.shape) for q in seqs]
    return FaultDetector(**kw).fit(seqs, names, weights)  # type: ignore[arg-type]


def _partner_drift(rng: np.random.Generator, n: int = 160) -> np.ndarray:
    """An aircraft whose WL1 ages in friction (its partner's friction ratio moves by 0.45 of
    the rise: the back-driven drag) and whose WT takes an eccentricity step."""
    z = _aircraft(rng, n)
    rise = 0.06 * np.maximum(np.arange(n) - 20, 0)
    z[:, NAMES.index("WL1.F_MTEL")] += rise
    z[:, NAMES.index("WL2.F_MTEL")] += 0.45 * rise
    z[120:, NAMES.index("WT.F_SE")] += 12.0
    return z


def _online(det: FaultDetector, z: np.ndarray, names: list[str], evidence: np.ndarray | None
            ) -> list[dict[str, DetectionResult]]:
    states = new_states(det, sorted({n.split(".")[0] for n in names}))
    out = []
    for i, row in enumerate(z):
        zd = dict(zip(names, row.tolist(), strict=True))
        ev = None if evidence is None else dict(zip(names, evidence[i].tolist(), strict=True))
        out.append(update_units(det, states, zd, evidence=ev))
    return out


def _as_arrays(results: list[dict[str, DetectionResult]], names: list[str]
               ) -> tuple[np.ndarray, np.ndarray]:
    conf = np.array([[r[n.split(".")[0]].confidence[n] for n in names] for r in results])
    held = np.array([[n in r[n.split(".")[0]].held for n in names] for r in results])
    return conf, held


def _first_online(results: list[dict[str, DetectionResult]]) -> dict[str, int | None]:
    first: dict[str, int | None] = dict.fromkeys(results[0])
    for i, r in enumerate(results):
        for u, res in r.items():
            if res.new_alarm:
                first[u] = i
    return first


@pytest.mark.parametrize("case", ["healthy", "partner drift"])
def test_the_vectorised_judge_is_the_online_one_pair_rule_included(case: str) -> None:
    rng = np.random.default_rng(31)
    det = _fitted(rng)
    z = _aircraft(rng, 160) if case == "healthy" else _partner_drift(rng)
    z[37, NAMES.index("WT.F_SE")] = np.nan
    evidence = rng.choice(WEIGHTS, size=z.shape)
    online = _online(det, z, NAMES, evidence)
    conf, held = _as_arrays(online, NAMES)
    judged = judge_sequence(det, z, NAMES, evidence)
    assert np.allclose(judged.confidence, conf, rtol=1e-9, atol=1e-12)
    assert np.array_equal(judged.held, held)
    assert first_alarms(det, z, NAMES, evidence) == _first_online(online)
    # the pair rule is exercised: on both drives, one flight or another
    assert held[:, NAMES.index("WL1.F_MTEL")].any() and held[:, NAMES.index("WL2.F_MTEL")].any()
    if case == "partner drift":
        first = _first_online(online)
        assert first["WL1"] is not None and first["WT"] is not None and first["WL2"] is None
        # the healthy partner's friction evidence reaches the alarm level, and is held
        wl2 = NAMES.index("WL2.F_MTEL")
        assert (judged.confidence[:, wl2] >= det.alarm_confidence).any()
        assert not judged.firing[:, wl2].any()


def test_the_healthy_statistics_are_what_the_online_judge_judges() -> None:
    """One window (3 flights, a mean): the online judge's confidence is Phi(S_3 - b_3), so
    its S_3 is read back from it; the bands are learned on the same values, and on -inf where
    the pair rule holds a drive's evidence (it raises no alarm there)."""
    rng = np.random.default_rng(32)
    det = _fitted(rng, windows=(3,), min_windows={}, band_floor=0.0)
    z = _aircraft(rng, 60)
    evidence = rng.choice(WEIGHTS, size=z.shape)
    conf, held = _as_arrays(_online(det, z, NAMES, evidence), NAMES)
    (stats,) = healthy_statistics(det, [z], NAMES, [evidence])
    for j, name in enumerate(NAMES):
        judged = conf[:, j] > 0.0  # a full window: confidence above 0 wherever judged
        s3 = ndtri(conf[judged, j]) + det.band_[j, 0]
        want = np.where(held[judged, j], -math.inf, s3)
        assert stats[j] == pytest.approx(want, rel=1e-6, abs=1e-6), name
    assert np.isneginf(stats[NAMES.index("WL2.F_MTEL")]).any()


def test_the_healthy_alarm_rate_counts_the_alarms_the_chain_would_raise() -> None:
    """The design's healthy rate (``healthy_alarm_rate``): the events and unit-flights of
    every aircraft's units judged together online, each unit at risk until its first alarm
    (here at a high stated rate, for events to count)."""
    rng = np.random.default_rng(33)
    names = list(AIRCRAFT_FEATURES)
    det = _fitted(rng, names, band_floor=0.0, false_alarm_rate=0.02)
    seqs = [_aircraft(rng, 80, names) for _ in range(6)]
    drift = 0.08 * np.maximum(np.arange(80) - 10, 0)
    seqs[0][:, names.index("WL2.F_MTEL")] += drift
    seqs[0][:, names.index("WL1.F_MTEL")] += 0.45 * drift
    weights = [rng.choice(WEIGHTS, size=q.shape) for q in seqs]
    events = unit_flights = 0
    for q, w in zip(seqs, weights, strict=True):
        first = _first_online(_online(det, q, names, w))
        events += sum(f is not None for f in first.values())
        unit_flights += sum(q.shape[0] if f is None else f + 1 for f in first.values())
    rate = healthy_alarm_rate(det, seqs, evidence=weights)
    assert (rate["events"], rate["unit_flights"]) == (events, unit_flights)
    assert events > 0
    # WL1's friction evidence (its partner's drag) is held: it raises no alarm of WL1's
    wl1 = _online(det, seqs[0], names, weights[0])[-1]["WL1"]
    assert "WL1.F_MTEL" in wl1.held and "WL1.F_MTEL" not in wl1.alarm_features
