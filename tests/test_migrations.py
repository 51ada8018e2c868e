"""Alembic: upgrade from empty, downgrade to base, and no drift between models and migrations."""

from __future__ import annotations

from typing import Any

from alembic.autogenerate import compare_metadata
from alembic.runtime.migration import MigrationContext
from sqlalchemy import Engine, create_engine, inspect

from server.config import Settings
from server.migrate import downgrade, head_revision, upgrade
from server.models import Base


def _fresh_url(settings: Settings) -> str:
    if settings.is_sqlite:
        settings.data_dir.mkdir(parents=True, exist_ok=True)
        return settings.effective_database_url
    url = settings.effective_database_url
    downgrade(url, "base")  # the session database starts at head
    return url


def test_upgrade_downgrade_and_no_drift(settings: Settings) -> None:
    url = _fresh_url(settings)
    engine = create_engine(url)
    upgrade(url)
    with engine.connect() as conn:
        ctx = MigrationContext.configure(conn)
        assert ctx.get_current_revision() == head_revision()
        diff = compare_metadata(ctx, Base.metadata)
    assert diff == [], f"models and migrations drift: {diff}"
    assert {"aircraft", "actuators", "flights", "jobs", "api_keys"} <= set(
        inspect(engine).get_table_names())

    downgrade(url, "base")
    engine.dispose()
    engine = create_engine(url)
    assert set(inspect(engine).get_table_names()) <= {"alembic_version"}
    upgrade(url)  # leave it at head for the next test on this database
    engine.dispose()


def test_prognosis_rows_keep_their_rul_across_0004(settings: Settings) -> None:
    """0004 turns the old five prognosis columns into the RulDistribution document and back."""
    import sqlalchemy as sa

    from server.phm.prognosis import RulDistribution
    from server.phm.prognosis.document import rul_quantile

    url = _fresh_url(settings)
    downgrade(url, "base")
    upgrade(url, "0003")
    engine = create_engine(url)
    with engine.begin() as conn:
        conn.execute(sa.text("INSERT INTO aircraft (id, tail, base, created_at) "
                             "VALUES (1, 'I-MIG', 'Turin', CURRENT_TIMESTAMP)"))
        conn.execute(sa.text("INSERT INTO actuators (id, aircraft_id, position, serial, "
                             "installed_at) VALUES (1, 1, 'WT', 'S-MIG', CURRENT_TIMESTAMP)"))
        conn.execute(sa.text(
            "INSERT INTO flights (id, aircraft_id, flight_code, status, reasons, sha256, "
            "size_bytes, blob_path, content_kind, flight_metadata, received_at, updated_at) "
            "VALUES (1, 1, 'F1', 'analyzed', '[]', 'x', 1, 'b', 'parquet', '{}', "
            "CURRENT_TIMESTAMP, CURRENT_TIMESTAMP)"))
        conn.execute(sa.text(
            "INSERT INTO prognoses (actuator_id, flight_id, flight_index, fault_mode, "
            "severity_mean, severity_std, rul_quantiles, p_fail_within, histogram, created_at) "
            "VALUES (1, 1, 7, 'DMD', 0.4, 0.05, :q, :p, :h, CURRENT_TIMESTAMP)"),
            {"q": '{"5": 20.0, "50": 40.0, "95": null}', "p": '{"10": 0.1}',
             "h": '{"edges": [0.0, 50.0], "mass": [0.9]}'})
    upgrade(url)
    with engine.connect() as conn:
        doc = conn.execute(sa.text("SELECT distribution FROM prognoses")).scalar_one()
    doc = doc if isinstance(doc, dict) else __import__("json").loads(doc)
    rul = RulDistribution.from_dict(doc)
    assert rul_quantile(doc, 0.05) == 20.0 and rul.median == 40.0
    assert rul.quantiles[0.95] == float("inf") and rul.p_fail_within == {10: 0.1}
    assert rul.severity_mean == 0.4 and rul.p_beyond_horizon == 0.09999999999999998
    downgrade(url, "0003")
    with engine.connect() as conn:
        row = conn.execute(sa.text("SELECT rul_quantiles, severity_std FROM prognoses")).one()
    quantiles = row[0] if isinstance(row[0], dict) else __import__("json").loads(row[0])
    assert quantiles == {"5": 20.0, "50": 40.0, "95": None} and row[1] == 0.05
    engine.dispose()
    downgrade(url, "base")
    upgrade(url)  # leave it at head for the next test on this database


def _insert_flight(conn, id_: int, code: str, kind: str, sha: str, metadata: dict,  # type: ignore[no-untyped-def]
                   status: str = "queued") -> None:
    import json

    import sqlalchemy as sa

    conn.execute(sa.text(
        "INSERT INTO flights (id, aircraft_id, flight_code, status, reasons, sha256, size_bytes, "
        "blob_path, content_kind, flight_metadata, received_at, updated_at) VALUES (:id, 1, "
        ":code, :status, '[]', :sha, 1, 'b', :kind, :meta, CURRENT_TIMESTAMP, "
        "CURRENT_TIMESTAMP)"),
        {"id": id_, "code": code, "status": status, "sha": sha, "kind": kind,
         "meta": json.dumps(metadata)})


def test_flights_keep_their_upload_identity_across_0005(settings: Settings) -> None:
    """0005 gives existing rows the upload key a new upload of the same file computes (so a
    retry stays idempotent), frees the content hash, and refuses to undo while it is shared."""
    import pytest
    import sqlalchemy as sa
    from sqlalchemy.exc import IntegrityError

    from server.services.flights import upload_key
    from tests.flightlog_factory import make_log

    url = _fresh_url(settings)
    downgrade(url, "base")
    upgrade(url, "0004")
    engine = create_engine(url)
    csv_meta = make_log("I-MIG", "F2").metadata.to_strings()  # as stored after decoding
    with engine.begin() as conn:
        conn.execute(sa.text("INSERT INTO aircraft (id, tail, base, created_at) "
                             "VALUES (1, 'I-MIG', 'Turin', CURRENT_TIMESTAMP)"))
        _insert_flight(conn, 1, "F1", "parquet", "a" * 64,
                       make_log("I-MIG", "F1").metadata.to_strings())
        _insert_flight(conn, 2, "F2", "csv", "b" * 64, csv_meta)
    upgrade(url)
    with engine.connect() as conn:
        keys = dict(conn.execute(sa.text("SELECT id, upload_key FROM flights")).all())
    assert keys[1] == upload_key(sha256="a" * 64, kind="parquet", form_metadata={"x": "y"})
    assert keys[2] == upload_key(sha256="b" * 64, kind="csv", form_metadata=csv_meta)
    with engine.begin() as conn:  # the same bytes again, rejected: allowed now
        conn.execute(sa.text(
            "INSERT INTO flights (id, aircraft_id, flight_code, status, reasons, sha256, "
            "upload_key, size_bytes, blob_path, content_kind, flight_metadata, received_at, "
            "updated_at) SELECT 3, aircraft_id, flight_code, 'rejected', reasons, sha256, "
            "upload_key, size_bytes, blob_path, content_kind, flight_metadata, received_at, "
            "updated_at FROM flights WHERE id = 1"))
    with pytest.raises(RuntimeError, match="shared by several flights"):
        downgrade(url, "0004")
    with engine.begin() as conn:
        conn.execute(sa.text("DELETE FROM flights WHERE id = 3"))
    downgrade(url, "0004")
    with pytest.raises(IntegrityError), engine.begin() as conn:  # unique content hash again
        _insert_flight(conn, 4, "F4", "parquet", "a" * 64, {})
    engine.dispose()
    downgrade(url, "base")
    upgrade(url)  # leave it at head for the next test on this database


def _status_values(engine, table: str) -> set[str]:  # type: ignore[no-untyped-def]
    """The values the database's ``ck_<table>_status`` allows, read back from the database
    (PostgreSQL rewrites ``IN`` as ``= ANY (ARRAY[...])``: the quoted values are what count)."""
    import re

    checks = {c["name"]: c["sqltext"] for c in inspect(engine).get_check_constraints(table)}
    return set(re.findall(r"'([^']*)'", str(checks[f"ck_{table}_status"])))


def _insert_statuses(conn, id_: int, flight: str, job: str) -> None:  # type: ignore[no-untyped-def]
    import sqlalchemy as sa

    conn.execute(sa.text(
        "INSERT INTO flights (id, aircraft_id, flight_code, status, reasons, sha256, upload_key, "
        "size_bytes, blob_path, content_kind, flight_metadata, received_at, updated_at) VALUES "
        "(:id, 1, :code, :status, '[]', :key, :key, 1, 'b', 'parquet', '{}', CURRENT_TIMESTAMP, "
        "CURRENT_TIMESTAMP)"),
        {"id": id_, "code": f"F{id_}", "status": flight, "key": f"{id_:064d}"})
    conn.execute(sa.text(
        "INSERT INTO jobs (id, kind, flight_id, lock_key, status, attempts, max_attempts, "
        "run_after, payload, created_at, updated_at) VALUES (:id, 'analyze_flight', :id, "
        "'aircraft:1', :status, 0, 5, CURRENT_TIMESTAMP, '{}', CURRENT_TIMESTAMP, "
        "CURRENT_TIMESTAMP)"), {"id": id_, "status": job})


def test_the_database_refuses_a_status_outside_the_vocabulary_from_0009(
        settings: Settings) -> None:
    """0009 holds ``flights.status`` and ``jobs.status`` to FlightStatus and JobStatus: rows
    written before it pass, a row with another status (or a member's name instead of its
    value) is refused by the database itself, not only by the code; 0008 again allows it."""
    from itertools import cycle

    import pytest
    import sqlalchemy as sa
    from sqlalchemy.exc import IntegrityError

    from server.vocabulary import FlightStatus, JobStatus

    url = _fresh_url(settings)
    downgrade(url, "base")
    upgrade(url, "0008")
    engine = create_engine(url)
    with engine.begin() as conn:
        conn.execute(sa.text("INSERT INTO aircraft (id, tail, base, created_at) "
                             "VALUES (1, 'I-MIG', 'Turin', CURRENT_TIMESTAMP)"))
        for i, (flight, job) in enumerate(zip(FlightStatus, cycle(JobStatus)), start=1):
            _insert_statuses(conn, i, flight, job)  # every status, as the code wrote them
    upgrade(url)
    assert _status_values(engine, "flights") == set(FlightStatus)
    assert _status_values(engine, "jobs") == set(JobStatus)
    for flight, job in (("lost", JobStatus.DONE), (FlightStatus.QUEUED, "finished"),
                        ("ANALYZED", JobStatus.DONE), (FlightStatus.QUEUED, "DEAD")):
        with pytest.raises(IntegrityError, match="ck_"), engine.begin() as conn:
            _insert_statuses(conn, 99, flight, job)
    with pytest.raises(IntegrityError, match="ck_flights_status"), engine.begin() as conn:
        conn.execute(sa.text("UPDATE flights SET status = 'deleted' WHERE id = 1"))

    downgrade(url, "0008")
    assert not {c["name"] for t in ("flights", "jobs")
                for c in inspect(engine).get_check_constraints(t)}
    with engine.begin() as conn:  # free text again, as before 0009
        _insert_statuses(conn, 99, "lost", "finished")
        conn.execute(sa.text("DELETE FROM jobs WHERE id = 99"))
        conn.execute(sa.text("DELETE FROM flights WHERE id = 99"))
    engine.dispose()
    downgrade(url, "base")
    upgrade(url)  # leave it at head for the next test on this database


def _live_injection(conn, id_: int, status: str = "pending") -> None:  # type: ignore[no-untyped-def]
    import sqlalchemy as sa

    conn.execute(sa.text(
        "INSERT INTO injections (id, aircraft_id, position, fault_mode, onset_flight, status, "
        "created_by, created_at) VALUES (:id, 1, 'WT', 'DMD', 0, :status, 't', "
        "CURRENT_TIMESTAMP)"), {"id": id_, "status": status})


def test_one_live_station_item_per_slot_from_0013(settings: Settings) -> None:
    """0013 refuses to index a database holding two live injections on one aircraft (and says
    which), takes it once one is cancelled, then the database refuses a second live one; 0012
    again allows it."""
    import pytest
    import sqlalchemy as sa
    from sqlalchemy.exc import IntegrityError

    url = _fresh_url(settings)
    downgrade(url, "base")
    upgrade(url, "0012")
    engine = create_engine(url)
    with engine.begin() as conn:
        conn.execute(sa.text("INSERT INTO aircraft (id, tail, base, created_at) "
                             "VALUES (1, 'I-MIG', 'Turin', CURRENT_TIMESTAMP)"))
        _live_injection(conn, 1, "active")
        _live_injection(conn, 2, "pending")
        _live_injection(conn, 3, "cancelled")
    with pytest.raises(RuntimeError, match="injections: more than one live item"):
        upgrade(url)
    with engine.begin() as conn:
        conn.execute(sa.text("UPDATE injections SET status = 'cancelled' WHERE id = 2"))
    upgrade(url)
    with pytest.raises(IntegrityError), engine.begin() as conn:
        _live_injection(conn, 4, "pending")
    with engine.begin() as conn:  # not live: no slot taken
        _live_injection(conn, 4, "failed")

    downgrade(url, "0012")
    with engine.begin() as conn:  # two live ones again, as before 0013
        _live_injection(conn, 5, "pending")
        conn.execute(sa.text("DELETE FROM injections"))
    engine.dispose()
    downgrade(url, "base")
    upgrade(url)  # leave it at head for the next test on this database


def _training(conn, id_: int, status: str) -> None:  # type: ignore[no-untyped-def]
    """A model version ``id_`` and its train_model job ``id_``, as the old endpoint queued."""
    import sqlalchemy as sa

    conn.execute(sa.text(
        "INSERT INTO model_versions (id, name, status, active, payload, training, metrics, "
        "created_at) VALUES (:id, 'm', 'training', false, '{}', '{}', '{}', CURRENT_TIMESTAMP)"),
        {"id": id_})
    conn.execute(sa.text(
        "INSERT INTO jobs (id, kind, lock_key, status, attempts, max_attempts, run_after, "
        "payload, created_at, updated_at) VALUES (:id, 'train_model', 'train_model', :status, "
        "0, 1, CURRENT_TIMESTAMP, :payload, CURRENT_TIMESTAMP, CURRENT_TIMESTAMP)"),
        {"id": id_, "status": status, "payload": f'{{"campaign": "c", "version_id": {id_}}}'})


def test_one_pending_training_from_0014(settings: Settings) -> None:
    """0014 keeps the slot for the running (else the earliest) pending training of a database
    that holds several, which the old endpoint allowed, and makes the other queued ones dead
    and their versions failed, saying why; then the database refuses a second pending one
    (finished ones never count); 0013 again allows it."""
    import pytest
    import sqlalchemy as sa
    from sqlalchemy.exc import IntegrityError

    url = _fresh_url(settings)
    downgrade(url, "base")
    upgrade(url, "0013")
    engine = create_engine(url)
    with engine.begin() as conn:
        for id_, status in ((1, "done"), (2, "dead"), (3, "queued"), (4, "running"),
                            (5, "queued")):
            _training(conn, id_, status)
    upgrade(url)
    with engine.connect() as conn:
        jobs = dict(conn.execute(sa.text("SELECT id, status FROM jobs")).all())
        buried = conn.execute(sa.text("SELECT last_error FROM jobs WHERE id = 3")).scalar_one()
        versions = dict(conn.execute(sa.text("SELECT id, status FROM model_versions")).all())
        error = conn.execute(sa.text("SELECT error FROM model_versions WHERE id = 5")).scalar()
    assert jobs == {1: "done", 2: "dead", 3: "dead", 4: "running", 5: "dead"}
    assert "job 4 held the slot" in buried and error == buried
    assert versions == {1: "training", 2: "training", 3: "failed", 4: "training", 5: "failed"}
    with pytest.raises(IntegrityError, match="uq_jobs_pending_training|UNIQUE"), \
            engine.begin() as conn:
        _training(conn, 6, "queued")
    with engine.begin() as conn:
        _training(conn, 7, "done")  # a finished one never holds the slot

    downgrade(url, "0013")
    with engine.begin() as conn:  # several pending again, as before 0014
        _training(conn, 8, "queued")
    engine.dispose()
    downgrade(url, "base")
    upgrade(url)  # leave it at head for the next test on this database


def _station_item(conn, table: str, id_: int, status: str, slot: int = 9) -> None:  # type: ignore[no-untyped-def]
    """A row of one test-station table with ``status`` in slot ``slot`` (of 1-9): the
    aircraft of a fault injection, the sensor of a sensor injection, a condition's kind."""
    import sqlalchemy as sa

    columns = {"injections": (":slot", "position, fault_mode", "'WT', 'DMD'"),
               "sensor_injections": ("1", "position, sensor, kind, value",
                                     "'WT', :name, 'noise', 2"),
               "sim_conditions": ("1", "kind, value", ":name, 1")}[table]
    conn.execute(sa.text(
        f"INSERT INTO {table} (id, aircraft_id, {columns[1]}, onset_flight, status, created_by, "
        f"created_at) VALUES (:id, {columns[0]}, {columns[2]}, 0, :status, 't', "
        "CURRENT_TIMESTAMP)"), {"id": id_, "status": status, "slot": slot, "name": f"s{slot}"})


def test_station_items_hold_their_status_to_the_vocabulary_from_0015(
        settings: Settings) -> None:
    """0015 holds the three test-station tables' ``status`` to StationStatus: rows of every
    status written before it pass, another is refused by the database, one live item per slot
    still holds (the partial index survives SQLite's table rebuild) and a second ended one is
    no slot; 0014 again allows any text."""
    import pytest
    import sqlalchemy as sa
    from sqlalchemy.exc import IntegrityError

    from server.vocabulary import StationStatus

    tables = ("injections", "sensor_injections", "sim_conditions")
    url = _fresh_url(settings)
    downgrade(url, "base")
    upgrade(url, "0014")
    engine = create_engine(url)
    with engine.begin() as conn:
        for i in range(1, 10):
            conn.execute(sa.text("INSERT INTO aircraft (id, tail, base, created_at) "
                                 "VALUES (:id, :tail, 'Turin', CURRENT_TIMESTAMP)"),
                         {"id": i, "tail": f"I-MIG{i}"})
        for table in tables:
            for i, status in enumerate(StationStatus, start=1):
                _station_item(conn, table, i, status, slot=i)
    upgrade(url)
    for table in tables:
        assert _status_values(engine, table) == set(StationStatus)
        for status in ("done", "PENDING"):
            with pytest.raises(IntegrityError, match=f"ck_{table}_status"), \
                    engine.begin() as conn:
                _station_item(conn, table, 99, status)
        with pytest.raises(IntegrityError), engine.begin() as conn:  # 1 holds a live one
            _station_item(conn, table, 99, StationStatus.ACTIVE, slot=1)
        with engine.begin() as conn:  # an ended one takes no slot
            _station_item(conn, table, 99, StationStatus.CANCELLED, slot=1)

    downgrade(url, "0014")
    assert not {c["name"] for t in tables for c in inspect(engine).get_check_constraints(t)}
    with engine.begin() as conn:  # free text again, as before 0015; the slots still held
        _station_item(conn, "injections", 100, "done")
        with pytest.raises(IntegrityError):
            with conn.begin_nested():
                _station_item(conn, "injections", 101, "pending", slot=1)
    engine.dispose()
    downgrade(url, "base")
    upgrade(url)  # leave it at head for the next test on this database


def _one_actuator_at(url: str, revision: str, position: str) -> Engine:
    """A fresh database at ``revision`` holding aircraft 1 with actuator 1 at ``position``."""
    import sqlalchemy as sa

    downgrade(url, "base")
    upgrade(url, revision)
    engine = create_engine(url)
    with engine.begin() as conn:
        conn.execute(sa.text("INSERT INTO aircraft (id, tail, base, created_at) "
                             "VALUES (1, 'I-MIG', 'Turin', CURRENT_TIMESTAMP)"))
        conn.execute(sa.text("INSERT INTO actuators (id, aircraft_id, position, serial, "
                             "installed_at) VALUES (1, 1, :p, 'S-MIG', CURRENT_TIMESTAMP)"),
                     {"p": position})
    return engine


def _alarm_and_version(conn, id_: int, alarm: str, version: str) -> None:  # type: ignore[no-untyped-def]
    """An alarm ``id_`` on its own flight ``id_`` of actuator 1, and a model version ``id_``."""
    import sqlalchemy as sa

    _insert_statuses(conn, id_, "analyzed", "done")
    conn.execute(sa.text(
        "INSERT INTO alarms (id, actuator_id, flight_id, status, confidence, features, "
        "created_at) VALUES (:id, 1, :id, :status, 0.9, '[]', CURRENT_TIMESTAMP)"),
        {"id": id_, "status": alarm})
    conn.execute(sa.text(
        "INSERT INTO model_versions (id, name, status, active, payload, training, metrics, "
        "created_at) VALUES (:id, 'm', :status, false, '{}', '{}', '{}', CURRENT_TIMESTAMP)"),
        {"id": id_, "status": version})


def test_alarm_and_model_statuses_held_to_the_vocabulary_from_0016(settings: Settings) -> None:
    """0016 holds ``alarms.status`` and ``model_versions.status`` to AlarmStatus and
    ModelVersionStatus: a database holding another value is not changed, the upgrade names
    the rows (in both tables); corrected, it upgrades, every status the code writes passes,
    any other is refused by the database; 0015 again allows it."""
    import pytest
    import sqlalchemy as sa
    from sqlalchemy.exc import IntegrityError

    from server.vocabulary import AlarmStatus, ModelVersionStatus

    url = _fresh_url(settings)
    engine = _one_actuator_at(url, "0015", "WT")
    with engine.begin() as conn:
        for i, (alarm, version) in enumerate(zip(AlarmStatus, ModelVersionStatus, strict=True),
                                             start=1):
            _alarm_and_version(conn, i, alarm, version)  # every status the code writes
        _alarm_and_version(conn, 8, "Open", "ready")
        _alarm_and_version(conn, 9, "closed", "archived")
    with pytest.raises(RuntimeError) as refused:
        upgrade(url)
    assert "alarms: 1 rows" in str(refused.value) and "8: 'Open'" in str(refused.value)
    assert "model_versions: 1 rows" in str(refused.value)
    assert "9: 'archived'" in str(refused.value)
    with engine.connect() as conn:  # nothing changed: still at 0015, without the constraints
        assert MigrationContext.configure(conn).get_current_revision() == "0015"
    assert not {c["name"] for t in ("alarms", "model_versions")
                for c in inspect(engine).get_check_constraints(t)}

    with engine.begin() as conn:
        conn.execute(sa.text("UPDATE alarms SET status = 'open' WHERE id = 8"))
        conn.execute(sa.text("UPDATE model_versions SET status = 'failed' WHERE id = 9"))
    upgrade(url)
    assert _status_values(engine, "alarms") == set(AlarmStatus)
    assert _status_values(engine, "model_versions") == set(ModelVersionStatus)
    for alarm, version in (("reopened", "ready"), ("OPEN", "ready"), ("open", "deleted"),
                           ("open", "READY")):
        with pytest.raises(IntegrityError, match="ck_"), engine.begin() as conn:
            _alarm_and_version(conn, 99, alarm, version)
    with pytest.raises(IntegrityError, match="ck_alarms_status"), engine.begin() as conn:
        conn.execute(sa.text("UPDATE alarms SET status = 'snoozed' WHERE id = 1"))

    downgrade(url, "0015")
    assert not {c["name"] for t in ("alarms", "model_versions")
                for c in inspect(engine).get_check_constraints(t)}
    with engine.begin() as conn:  # free text again, as before 0016
        _alarm_and_version(conn, 99, "snoozed", "archived")
    engine.dispose()
    downgrade(url, "base")
    upgrade(url)  # leave it at head for the next test on this database


def _fault(conn, id_: int, status: str, position: str, mode: str) -> None:  # type: ignore[no-untyped-def]
    """A fault injection ``id_`` on aircraft 1."""
    import sqlalchemy as sa

    conn.execute(sa.text(
        "INSERT INTO injections (id, aircraft_id, position, fault_mode, onset_flight, status, "
        "created_by, created_at) VALUES (:id, 1, :position, :mode, 0, :status, 't', "
        "CURRENT_TIMESTAMP)"), {"id": id_, "status": status, "position": position, "mode": mode})


def test_concurrent_fault_injections_one_live_per_mode_of_an_actuator_from_0017(
        settings: Settings) -> None:
    """0017 lets an aircraft hold live injections on other actuators and of other modes on one
    actuator, and the database still refuses a second live one of the same mode on the same
    actuator; a downgrade to one per aircraft names the aircraft holding more and changes
    nothing, and once all but one are cancelled it holds one per aircraft again."""
    import pytest
    import sqlalchemy as sa
    from sqlalchemy.exc import IntegrityError

    url = _fresh_url(settings)
    downgrade(url, "base")
    upgrade(url, "0016")
    engine = create_engine(url)
    with engine.begin() as conn:
        conn.execute(sa.text("INSERT INTO aircraft (id, tail, base, created_at) "
                             "VALUES (1, 'I-MIG', 'Turin', CURRENT_TIMESTAMP)"))
        _fault(conn, 1, "active", "WT", "DMD")
    with pytest.raises(IntegrityError), engine.begin() as conn:  # one per aircraft before
        _fault(conn, 2, "pending", "WL1", "TTS")
    upgrade(url)
    with engine.begin() as conn:
        _fault(conn, 2, "pending", "WT", "TTS")  # another mode on the same actuator
        _fault(conn, 3, "active", "WL1", "DMD")  # the same mode on another actuator
        _fault(conn, 4, "cancelled", "WT", "DMD")  # an ended one holds no slot
    with pytest.raises(IntegrityError, match="uq_injections_live|UNIQUE"), \
            engine.begin() as conn:
        _fault(conn, 5, "pending", "WT", "DMD")

    with pytest.raises(RuntimeError, match=r"more than one live injection on an aircraft "
                       r"\(aircraft 1: 3\)"):
        downgrade(url, "0016")
    with engine.connect() as conn:  # 0017's own step changed nothing; PostgreSQL rolls the
        # whole downgrade back (one transaction), SQLite keeps the later revisions' steps
        assert MigrationContext.configure(conn).get_current_revision() in (
            "0017", head_revision())
    with engine.begin() as conn:
        conn.execute(sa.text("UPDATE injections SET status = 'cancelled' WHERE id IN (2, 3)"))
    downgrade(url, "0016")  # one live per aircraft again: 0017 goes down
    with pytest.raises(IntegrityError), engine.begin() as conn:
        _fault(conn, 6, "pending", "WL2", "MTEL")
    with engine.begin() as conn:
        conn.execute(sa.text("DELETE FROM injections"))
    engine.dispose()
    downgrade(url, "base")
    upgrade(url)  # leave it at head for the next test on this database


def _alarm_json_column_across(url: str, before: str, column: str, value: Any) -> Engine:
    """An alarm raised at revision ``before`` and one raised after the next revision, which
    adds the JSON ``alarms.column``: the first has none (null), the second keeps ``value``;
    going down to ``before`` drops the column and keeps both alarms. Returns the engine, at
    ``before``."""
    import json

    import sqlalchemy as sa

    engine = _one_actuator_at(url, before, "WL1")
    with engine.begin() as conn:
        _alarm_and_version(conn, 1, "open", "ready")
    upgrade(url)
    with engine.begin() as conn:
        _alarm_and_version(conn, 2, "open", "ready")
        conn.execute(sa.text(f"UPDATE alarms SET {column} = :v WHERE id = 2"),
                     {"v": json.dumps(value)})
        rows = dict(conn.execute(sa.text(f"SELECT id, {column} FROM alarms")).all())
    assert rows[1] is None
    assert (json.loads(rows[2]) if isinstance(rows[2], str) else rows[2]) == value
    downgrade(url, before)
    assert column not in {c["name"] for c in inspect(engine).get_columns("alarms")}
    with engine.begin() as conn:
        assert conn.execute(sa.text("SELECT COUNT(*) FROM alarms")).scalar() == 2
    return engine


def test_an_alarm_keeps_its_ambiguity_group_from_0018(settings: Settings) -> None:
    """0018 adds ``alarms.isolation``: an alarm raised before has none (null), one raised
    after keeps its units and probabilities; going down drops the column and keeps the
    alarms and their constraints."""
    import pytest
    import sqlalchemy as sa
    from sqlalchemy.exc import IntegrityError

    url = _fresh_url(settings)
    engine = _alarm_json_column_across(url, "0017", "isolation", {"WL1": 0.8, "WL2": 0.2})
    with pytest.raises(IntegrityError, match="ck_alarms_status"), engine.begin() as conn:
        conn.execute(sa.text("UPDATE alarms SET status = 'snoozed' WHERE id = 1"))
    engine.dispose()
    downgrade(url, "base")
    upgrade(url)  # leave it at head for the next test on this database


def test_an_alarm_keeps_its_modes_present_from_0019(settings: Settings) -> None:
    """0019 adds ``alarms.modes``: an alarm raised before has none (null), one raised after
    keeps every mode present; going down drops the column and keeps the alarms."""
    url = _fresh_url(settings)
    modes = [{"mode": "TTS", "probability": 0.9, "rul_median_flights": 40.0},
             {"mode": "DMD", "probability": 0.7, "rul_median_flights": None}]
    _alarm_json_column_across(url, "0018", "modes", modes).dispose()
    downgrade(url, "base")
    upgrade(url)  # leave it at head for the next test on this database
