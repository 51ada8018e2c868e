"""The chain itself (server.phm.chain), flight by flight on simulated verification flights,
with the model trained on the design campaign: what it says for a healthy aircraft and for a
growing fault, and that an actuator's state survives its JSON round trip between flights
(what the service does) without changing a single figure."""

from __future__ import annotations

import json
import math

import pytest

from server.phm.chain import (
    ActuatorHealth,
    PhmModel,
    analyze_flight,
    read_model_document,
)
from server.phm.dataset import Campaign, Pattern, reads_rod_ends_as_pair
from server.vocabulary import POSITIONS, alarming_positions

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def model(shipped_model) -> PhmModel:  # type: ignore[no-untyped-def]
    return read_model_document(shipped_model[0])


def _pattern(campaign: Campaign, mode: str) -> Pattern:
    return next(p for p in campaign.patterns if p.mode == mode)


def _run(model: PhmModel, p: Pattern, *, round_trip: bool):  # type: ignore[no-untyped-def]
    health = {pos: model.new_health(pos) for pos in POSITIONS}
    outcomes = []
    for r in p.flights:
        if round_trip:
            health = {pos: ActuatorHealth.from_dict(json.loads(json.dumps(h.to_dict())))
                      for pos, h in health.items()}
        outcomes.append(analyze_flight(model, r.features, health, seed=7,
                                       flight_index=r.index, started_at=r.started_at,
                                       base=p.base))
    return outcomes, health


def test_healthy_aircraft_raises_no_alarm(model, verification_campaign) -> None:  # type: ignore[no-untyped-def]
    outcomes, health = _run(model, _pattern(verification_campaign, "healthy"), round_trip=False)
    assert len(outcomes) > 10
    for out in outcomes:
        for o in out.values():
            assert not o.alarm and o.rul is None and o.class_probabilities is None
            assert o.z and 0.0 <= o.max_confidence < 0.98
    assert all(h.prognosis is None and h.alarm_index is None for h in health.values())


def test_growing_fault_is_alarmed_classified_and_given_a_rul(model, verification_campaign
                                                               ) -> None:  # type: ignore[no-untyped-def]
    p = _pattern(verification_campaign, "TTS")
    outcomes, health = _run(model, p, round_trip=False)
    faulty = alarming_positions(p.mode, p.position, pair_rod_ends=reads_rod_ends_as_pair(p))
    first = next(i for i, out in enumerate(outcomes) if out[p.position].alarm)
    assert p.flights[first].index >= int(p.onset_flight)  # never before the onset
    last = outcomes[-1][p.position]
    assert last.fault_mode == "TTS" and math.isclose(sum(last.class_probabilities.values()), 1.0)
    assert last.rul is not None and 0.0 < last.rul.median < 2 * p.flights[-1].true_rul_flights + 50
    assert health[p.position].prognosis is not None
    for pos in set(POSITIONS) - faulty:
        assert not any(out[pos].alarm for out in outcomes)


def test_state_round_trip_between_flights_changes_nothing(model, verification_campaign
                                                          ) -> None:  # type: ignore[no-untyped-def]
    p = _pattern(verification_campaign, "MTWEAR")
    in_memory, _ = _run(model, p, round_trip=False)
    stored, _ = _run(model, p, round_trip=True)
    for a, b in zip(in_memory, stored, strict=True):
        for pos in POSITIONS:
            x, y = a[pos], b[pos]
            assert (x.alarm, x.fault_mode, x.z, x.confidence) == (y.alarm, y.fault_mode, y.z,
                                                                  y.confidence)
            assert (x.rul is None) == (y.rul is None)
            if x.rul is not None:
                assert x.rul.to_dict() == y.rul.to_dict()


def test_flight_index_must_increase(model, verification_campaign) -> None:  # type: ignore[no-untyped-def]
    r = _pattern(verification_campaign, "healthy").flights[0]
    health = {"WT": model.new_health("WT")}
    analyze_flight(model, r.features, health, flight_index=5)
    with pytest.raises(ValueError, match="flight_index must increase"):
        analyze_flight(model, r.features, health, flight_index=5)


def test_model_document_reader_unwraps_a_version_record(shipped_model) -> None:  # type: ignore[no-untyped-def]
    doc = shipped_model[0]
    assert read_model_document({"payload": doc, "id": 3}).to_dict() == \
        read_model_document(doc).to_dict()
    with pytest.raises(ValueError, match="older chain"):
        read_model_document({**doc, "format": "ema-phm-model/4"})


def test_repeated_evidence_is_pooled_not_multiplied(model, verification_campaign) -> None:  # type: ignore[no-untyped-def]
    """Flights since an alarm are not independent views of the fault: the same flight's
    evidence seen again and again leaves the class probabilities at that flight's own
    (calibrated) ones instead of driving them to certainty."""
    from server.phm.chain.inputs import classifier_vector
    from server.phm.chain.run import _classify

    p = _pattern(verification_campaign, "MTEL")
    outcomes, health = _run(model, p, round_trip=False)
    h = health[p.position]
    single = model.classifier.predict_proba(
        classifier_vector(h.detection, p.position)[None, :])[0]
    classes = [str(c) for c in model.classifier.classes_.tolist()]
    h.class_log_prob, h.class_weight = None, None
    for _ in range(25):
        probs = _classify(model, h, p.position)
    for c, v in zip(classes, single, strict=True):
        assert probs[c] == pytest.approx(float(v), abs=1e-9)
