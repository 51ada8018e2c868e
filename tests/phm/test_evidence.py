"""A flight's scatter follows its evidence: the sampling share of each feature's flight noise,
learned on healthy histories of mixed recording lengths, widens a short recording's test and
tightens a long one's, in the online judge and the vectorised sequence alike."""

from __future__ import annotations

import json

import numpy as np
import pytest

from server.phm.detection import (
    DetectionState,
    FaultDetector,
    confidence_sequence,
    evidence_shares,
)
from tests.phm.judging import judge_alone

NAMES = ["WT.F_DMD", "WT.F_TTS"]
SHARE = {"WT.F_DMD": 0.8, "WT.F_TTS": 0.0}  # DMD mostly sampling noise; TTS none
#: evidence weights of 60, 120 and 300 s recordings against a design of 60 s ones
WEIGHTS = (1.0, 0.5, 0.2)


def _histories(rng: np.random.Generator, n_hist: int, n_flights: int,
               weights: tuple[float, ...] = WEIGHTS) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Healthy histories: an actuator offset (sd 1) plus flight noise of variance
    ``1 - a + a w`` per feature, ``w`` drawn per flight from ``weights``."""
    zs, ws = [], []
    a = np.array([SHARE[n] for n in NAMES])
    for _ in range(n_hist):
        w = rng.choice(weights, size=(n_flights, len(NAMES)))
        noise = rng.standard_normal((n_flights, len(NAMES))) * np.sqrt(1 - a + a * w)
        zs.append(rng.standard_normal(len(NAMES)) + noise)
        ws.append(w)
    return zs, ws


def test_the_sampling_share_is_recovered_from_mixed_recordings() -> None:
    zs, ws = _histories(np.random.default_rng(1), 40, 60)
    share = evidence_shares(zs, ws, [[0], [1]])
    assert share[0] == pytest.approx(0.8, abs=0.08)
    assert share[1] == pytest.approx(0.0, abs=0.08)


def test_one_recording_length_teaches_no_share() -> None:
    zs, ws = _histories(np.random.default_rng(2), 40, 60, weights=(1.0,))
    assert np.all(evidence_shares(zs, ws, [[0], [1]]) == 0.0)


def _fitted(rng: np.random.Generator) -> FaultDetector:
    zs, ws = _histories(rng, 40, 60)
    return FaultDetector(pool_positions=False).fit(zs, NAMES, ws)


def test_a_short_recording_is_judged_on_its_wider_scatter() -> None:
    """Self-referenced residuals of healthy 30 s flights (w = 2) have unit scatter with the
    evidence, 1.34 without; 300 s ones (w = 0.2) 0.6 without, 0.8-1 with (the reference's
    own uncertainty is still taken at typical evidence: a long recording's test is tighter,
    never looser than its healthy scatter)."""
    rng = np.random.default_rng(3)
    det = _fitted(rng)
    for w, band_with, sd_without in ((2.0, (0.9, 1.1), 1.34), (0.2, (0.75, 1.0), 0.6)):
        zs, ws = _histories(rng, 60, 40, weights=(w,))
        with_ev = np.concatenate([det.self_referenced(
            z, det.evidence_extra(e))[10:, 0] for z, e in zip(zs, ws, strict=True)])
        without = np.concatenate([det.self_referenced(z)[10:, 0] for z in zs])
        assert band_with[0] <= np.std(with_ev) <= band_with[1], w
        assert np.std(without) == pytest.approx(sd_without, abs=0.12), w


def test_online_judge_matches_the_vectorised_sequence_with_evidence() -> None:
    rng = np.random.default_rng(4)
    det = _fitted(rng)
    seq = np.c_[rng.normal(0.5, 1.0, 30), rng.normal(0, 1, 30)]
    seq[20:, 0] += 2.5
    weights = rng.choice(WEIGHTS + (2.0,), size=seq.shape)
    want = confidence_sequence(det, seq, NAMES, weights)
    st = DetectionState.new("WT", NAMES)
    got = [judge_alone(det, st, dict(zip(NAMES, row.tolist(), strict=True)),
                      evidence=dict(zip(NAMES, w.tolist(), strict=True)))
           for row, w in zip(seq, weights, strict=True)]
    assert np.allclose([[r.confidence[n] for n in NAMES] for r in got], want)
    # the evidence matters: judged as typical flights the confidences differ
    assert not np.allclose(confidence_sequence(det, seq, NAMES), want)


def test_the_share_survives_the_document_and_an_old_document_has_none() -> None:
    det = _fitted(np.random.default_rng(5))
    doc = json.loads(json.dumps(det.to_dict()))
    again = FaultDetector.from_dict(doc)
    assert np.array_equal(again.evidence_variance_, det.evidence_variance_)
    assert det.evidence_variance_[0] > 0
    del doc["evidence_variance"]
    old = FaultDetector.from_dict(doc)
    assert old.flight_variance({"WT.F_DMD": 3.0}, {"WT.F_TTS": 0.5}) == {"WT.F_TTS": 0.5}
    assert det.flight_variance({"WT.F_DMD": 3.0})["WT.F_DMD"] == pytest.approx(
        2.0 * det.evidence_variance_[0])
