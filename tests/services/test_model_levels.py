"""The detector levels the actuator page plots (server.services.models.detector_levels): the
defaults without a usable model version, the version's own otherwise, and a document in the
current format that fails to decode is an error, not a quiet fall back to the defaults."""

from __future__ import annotations

import copy
from collections.abc import Iterator

import pytest
from sqlalchemy.orm import Session

from server.config import Settings
from server.db import make_engine, make_session_factory
from server.demo_model import load_demo_model
from server.migrate import ensure_schema
from server.phm.chain import read_model_document
from server.phm.detection import FaultDetector
from server.services import models as model_service

FEATURES = ["WT.F_MTEL", "WT.F_DMD"]


@pytest.fixture
def session(tmp_path) -> Iterator[Session]:  # type: ignore[no-untyped-def]
    url = Settings(data_dir=tmp_path).effective_database_url
    engine = make_engine(url)
    ensure_schema(engine, url, auto_upgrade=True)
    with make_session_factory(engine)() as s:
        yield s
    engine.dispose()


def _defaults() -> model_service.DetectorLevels:
    d = FaultDetector()
    return model_service.DetectorLevels(d.band_floor, d.band_floor + d.z_alarm,
                                        d.alarm_confidence)


def _store(session: Session, payload: dict) -> int:  # type: ignore[type-arg]
    return model_service.store_trained(session=session, name="m", payload=payload, report={},
                                       make_active=False).id


def test_without_a_usable_model_version_the_defaults(session: Session) -> None:
    untrained = model_service.create_version(session=session, name="t", training={}).id
    older = _store(session, {"format": "ema-phm-model/1"})
    for version_id in (None, 999, untrained, older):
        assert model_service.detector_levels(session=session, version_id=version_id,
                                             features=FEATURES) == _defaults(), version_id


def test_a_model_version_gives_its_own_detector_levels(session: Session) -> None:
    payload = load_demo_model()["payload"]
    version_id = _store(session, payload)
    detector = read_model_document(payload).detector
    levels = model_service.detector_levels(session=session, version_id=version_id,
                                           features=FEATURES)
    bands = detector.bands()
    assert all(f in bands for f in FEATURES)
    assert levels.band == max(bands[f][0] for f in FEATURES)  # the upper median of two
    assert levels.threshold == levels.band + detector.z_alarm


def test_a_current_document_that_fails_to_decode_is_an_error(session: Session) -> None:
    payload = copy.deepcopy(load_demo_model()["payload"])
    payload["prognoser"]["n_particles"] = 1
    version_id = _store(session, payload)
    with pytest.raises(ValueError, match="n_particles"):
        model_service.detector_levels(session=session, version_id=version_id,
                                      features=FEATURES)
