"""The analysis service (server.services.analysis) on a real database: a fault pattern's
flights analysed one by one store what the chain says (health records, one alarm on the
faulty actuator, prognoses holding the filter's RUL document), an analysed flight is never
analysed twice, and a rejected flight says why."""

from __future__ import annotations

import json
from datetime import timezone

import pytest
from sqlalchemy import func, select

from server.campaigns import load_campaign
from server.models import Actuator, Alarm, Flight, HealthRecord, Prognosis
from server.phm.chain import analyze_flight, read_model_document
from server.services import analysis, fleet
from server.services import models as model_service

pytestmark = pytest.mark.slow


def _register(session, campaign, pattern) -> dict[int, object]:  # type: ignore[no-untyped-def]
    """The pattern's aircraft and one queued flight row per flight (flight id -> record)."""
    info = next(a for a in campaign.aircraft if a["tail"] == pattern.aircraft)
    aircraft = fleet.create_aircraft(session=session, tail=info["tail"], base=info["base"],
                                     serials=info["serials"])
    rows = {}
    for r in pattern.flights:
        f = Flight(aircraft_id=aircraft.id, tail=aircraft.tail, flight_code=r.flight,
                   status="queued", reasons=[], sha256=r.flight.ljust(64, "0")[:64],
                   size_bytes=1, blob_path=f"{r.flight}.parquet", content_kind="parquet",
                   flight_metadata={}, started_at=r.started_at)
        session.add(f)
        session.flush()
        rows[f.id] = r
    return rows


def test_fault_pattern_stored_as_the_chain_says(factory, shipped_model,  # type: ignore[no-untyped-def]
                                                verification_campaign_dir) -> None:
    campaign = load_campaign(verification_campaign_dir)
    pattern = next(p for p in campaign.patterns if p.mode == "DMD")
    with factory() as session:
        version = model_service.store_trained(session=session, name="t",
                                              payload=shipped_model[0],
                                              report=shipped_model[1], make_active=True)
        flights = _register(session, campaign, pattern)
        session.commit()
        model_id = version.id

    # the service's run, flight by flight, each in its own unit of work
    for flight_id, r in flights.items():
        with factory() as session:
            todo = analysis.flight_to_analyse(session=session, flight_id=flight_id)
            assert todo is not None and todo.flight_id == flight_id
            active_id, model = model_service.active_model(session=session)
            assert active_id == model_id
            analysis.store_analysis(session=session, flight_id=flight_id, features=r.features,
                                    model_id=model_id, model=model)
            session.commit()

    # the same flights through the chain in memory, as the service seeds it (flight ids)
    chain = read_model_document(shipped_model[0])
    health = {pos: chain.new_health(pos) for pos in ("WL1", "WL2", "WT")}
    expected = {fid: analyze_flight(chain, r.features, health, seed=fid,
                                    started_at=r.started_at.astimezone(timezone.utc),
                                    base=pattern.base)
                for fid, r in flights.items()}

    with factory() as session:
        assert session.scalar(select(func.count()).select_from(HealthRecord)) == 3 * len(flights)
        assert {f.status for f in session.scalars(select(Flight))} == {"analyzed"}
        faulty = session.scalar(select(Actuator).where(Actuator.position == pattern.position))
        alarms = list(session.scalars(select(Alarm)))
        assert [a.actuator_id for a in alarms] == [faulty.id]
        progs = list(session.scalars(select(Prognosis).order_by(Prognosis.flight_id)))
        assert progs, "a DMD run to failure gets RUL predictions"
        for p in progs:
            rul = expected[p.flight_id][pattern.position].rul
            assert p.fault_mode == "DMD"
            assert p.distribution == json.loads(json.dumps(analysis.json_safe(rul.to_dict())))
        assert alarms[0].fault_mode == expected[max(flights)][pattern.position].fault_mode

        # an analysed flight is finished: nothing to do, nothing written again
        last = max(flights)
        assert analysis.flight_to_analyse(session=session, flight_id=last) is None
        analysis.store_analysis(session=session, flight_id=last, features=flights[last].features,
                                model_id=model_id, model=chain)
        session.commit()
        assert session.scalar(select(func.count()).select_from(HealthRecord)) == 3 * len(flights)


def test_rejected_flight_keeps_its_reasons(factory) -> None:  # type: ignore[no-untyped-def]
    with factory() as session:
        aircraft = fleet.create_aircraft(session=session, tail="T-REJ", base="Turin",
                                         serials={"WL1": "a", "WL2": "b", "WT": "c"})
        f = Flight(aircraft_id=aircraft.id, tail="T-REJ", flight_code="F1", status="queued",
                   reasons=[], sha256="f" * 64, size_bytes=1, blob_path="x", content_kind="csv",
                   flight_metadata={})
        session.add(f)
        session.commit()
        reasons = [{"code": "blob_corrupt", "message": "m", "details": {}}]
        analysis.reject(session=session, flight_id=f.id, reasons=reasons)
        session.commit()
        assert analysis.flight_to_analyse(session=session, flight_id=f.id) is None
        assert session.get(Flight, f.id).reasons == reasons
