"""Flight upload: formats, every rejection reason, idempotency, conflicts, limits, read-back."""

from __future__ import annotations

import gzip
import io
import json

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
import scipy.io
from fastapi.testclient import TestClient

from server.flightlog import FlightLog
from server.vocabulary import FlightStatus, JobStatus
from tests.api.conftest import auth
from tests.flightlog_factory import make_log, make_parquet, serials_for

PARQUET = {"Content-Type": "application/vnd.apache.parquet"}


def raw_parquet(log: FlightLog, *, channels: dict[str, np.ndarray] | None = None,
                meta: dict[str, str] | None = None) -> bytes:
    """Parquet written without the writer's guards, to build broken files on purpose."""
    cols = channels if channels is not None else log.channels
    table = pa.table({k: pa.array(v) for k, v in cols.items()})
    m = meta if meta is not None else log.metadata.to_strings()
    table = table.replace_schema_metadata({k.encode(): v.encode() for k, v in m.items()})
    sink = io.BytesIO()
    pq.write_table(table, sink)
    return sink.getvalue()


def post_parquet(client: TestClient, key: str, data: bytes):  # type: ignore[no-untyped-def]
    return client.post("/api/v1/flights", content=data, headers={**PARQUET, **auth(key)})


def test_parquet_upload_accepted_listed_and_signals(client: TestClient, keys: dict[str, str],
                                                    aircraft: str) -> None:
    r = post_parquet(client, keys["uploader"], make_parquet(aircraft, "F0001"))
    assert r.status_code == 202, r.text
    body = r.json()
    assert body["status"] == "queued" and body["duplicate"] is False
    status = client.get(body["status_url"], headers=auth(keys["viewer"])).json()
    assert status["aircraft"] == aircraft and status["flight"] == "F0001"
    assert status["reasons"] == [] and status["uploader"] == "test-uploader"

    listing = client.get(f"/api/v1/flights?aircraft={aircraft}", headers=auth(keys["viewer"]))
    assert listing.json()["total"] == 1

    sig = client.get(f"/api/v1/flights/{body['id']}/signals?channels=WL1.ia,WT.x&max_points=100",
                     headers=auth(keys["viewer"])).json()
    assert set(sig["channels"]) == {"WL1.ia", "WT.x"}
    assert len(sig["t"]) <= 100 and sig["decimation"] == 96  # 9600 samples / 100
    unknown = client.get(f"/api/v1/flights/{body['id']}/signals?channels=WL1.nope",
                         headers=auth(keys["viewer"]))
    assert unknown.status_code == 404 and unknown.json()["error"]["code"] == "unknown_channel"


def test_same_bytes_idempotent_other_bytes_conflict(client: TestClient, keys: dict[str, str],
                                                    aircraft: str) -> None:
    data = make_parquet(aircraft, "F0002")
    first = post_parquet(client, keys["uploader"], data)
    second = post_parquet(client, keys["uploader"], data)
    assert first.status_code == 202 and second.status_code == 200
    assert second.json()["id"] == first.json()["id"] and second.json()["duplicate"] is True
    other = post_parquet(client, keys["uploader"], make_parquet(aircraft, "F0002", seed=9))
    assert other.status_code == 409 and other.json()["error"]["code"] == "flight_exists"
    assert client.get("/api/v1/flights", headers=auth(keys["viewer"])).json()["total"] == 1


def test_multipart_csv_gzip_and_mat(client: TestClient, keys: dict[str, str], aircraft: str
                                    ) -> None:
    for i, kind in enumerate(("csv", "csv.gz", "mat")):
        log = make_log(aircraft, f"M{i}")
        names = list(log.channels)
        if kind == "mat":
            buf = io.BytesIO()
            scipy.io.savemat(buf, {n.replace(".", "_"): log.channels[n] for n in names})
            data = buf.getvalue()
        else:
            matrix = np.column_stack([log.channels[n] for n in names])
            text = io.StringIO()
            np.savetxt(text, matrix, delimiter=",", header=",".join(names), comments="",
                       fmt="%.9g")
            data = text.getvalue().encode()
            if kind == "csv.gz":
                data = gzip.compress(data)
        r = client.post("/api/v1/flights", headers=auth(keys["uploader"]),
                        files={"file": (f"flight.{kind}", data)},
                        data=log.metadata.to_strings())
        assert r.status_code == 202, (kind, r.text)
        got = client.get(f"/api/v1/flights/{r.json()['id']}/signals?channels=WL2.x",
                         headers=auth(keys["viewer"])).json()
        step = got["decimation"]
        assert np.allclose(got["channels"]["WL2.x"][:5], log.channels["WL2.x"][::step][:5],
                           atol=1e-7)


def _with(log: FlightLog, **changes: np.ndarray) -> dict[str, np.ndarray]:
    ch = dict(log.channels)
    ch.update(changes)
    return ch


def _rejections(aircraft: str) -> list[tuple[str, bytes]]:
    log = make_log(aircraft, "R1", seed=1)
    n = log.n_samples
    t = log.channels["t"]
    meta = log.metadata.to_strings()
    cases: list[tuple[str, bytes]] = []
    full = make_parquet(aircraft, "R0")
    cases.append(("unreadable", full[: len(full) // 2]))
    cases.append(("unknown_format", raw_parquet(log, meta={**meta, "format": "ema-flightlog/9"})))
    cases.append(("missing_metadata", raw_parquet(log, meta={k: v for k, v in meta.items()
                                                              if k != "started_at"})))
    cases.append(("bad_metadata", raw_parquet(log, meta={**meta, "block_hours": "lots"})))
    cases.append(("missing_channels", raw_parquet(log, channels={
        k: v for k, v in log.channels.items() if k != "WL1.ia"})))
    cases.append(("extra_channels", raw_parquet(log, channels=_with(log, **{
        "WL1.extra": np.zeros(n, np.float32)}))))
    cases.append(("wrong_dtype", raw_parquet(log, channels=_with(log, **{
        "WL1.ia": log.channels["WL1.ia"].astype(np.float64)}))))
    nan = log.channels["WL2.va"].copy()
    nan[100] = np.nan
    cases.append(("non_finite", make_parquet_from(log, **{"WL2.va": nan})))
    back = t.copy()
    back[500] = back[498]
    cases.append(("time_not_monotonic", make_parquet_from(log, t=back)))
    gap = t.copy()
    gap[4000:] += 0.01
    cases.append(("time_gap", make_parquet_from(log, t=gap)))
    cases.append(("sample_rate_off", make_parquet_from(log, t=t * 1.05)))
    big = log.channels["WT.ib"].copy()
    big[10] = 80.0
    cases.append(("current_out_of_range", make_parquet_from(log, **{"WT.ib": big})))
    far = log.channels["WL1.x"].copy()
    far[10] = 0.2
    cases.append(("position_out_of_range", make_parquet_from(log, **{"WL1.x": far})))
    cases.append(("stuck_sensor", make_parquet_from(log, **{"WL2.theta": np.full(n, 1.5)})))
    short = make_log(aircraft, "R2", duration_s=3.0)
    cases.append(("too_short", make_parquet_from(short)))
    cases.append(("unknown_aircraft", make_parquet("GHOST", "R3")))
    cases.append(("serial_mismatch", make_parquet(aircraft, "R4", serials={
        "WL1": "SN-OTHER", "WL2": f"SN-WL2-{aircraft}", "WT": f"SN-WT-{aircraft}"})))
    return cases


def make_parquet_from(log: FlightLog, **changes: np.ndarray) -> bytes:
    from server.flightlog import write_parquet

    return write_parquet(FlightLog(log.metadata, _with(log, **changes)))


REASONS = ["unreadable", "unknown_format", "missing_metadata", "bad_metadata", "missing_channels",
           "extra_channels", "wrong_dtype", "non_finite", "time_not_monotonic", "time_gap",
           "sample_rate_off", "current_out_of_range", "position_out_of_range", "stuck_sensor",
           "too_short", "unknown_aircraft", "serial_mismatch"]


def test_every_rejection_reason(client: TestClient, keys: dict[str, str], aircraft: str) -> None:
    cases = _rejections(aircraft)
    assert [c for c, _ in cases] == REASONS
    for code, data in cases:
        r = post_parquet(client, keys["uploader"], data)
        assert r.status_code == 422, (code, r.text)
        err = r.json()["error"]
        assert err["code"] == "incoherent_flight"
        codes = [reason["code"] for reason in err["details"]["reasons"]]
        assert code in codes, (code, codes)
        assert all(reason["message"] for reason in err["details"]["reasons"])
        stored = client.get(f"/api/v1/flights/{err['details']['id']}",
                            headers=auth(keys["viewer"])).json()
        assert stored["status"] == "rejected" and code in [x["code"] for x in stored["reasons"]]
    rejected = client.get("/api/v1/flights?status=rejected&limit=5", headers=auth(keys["viewer"]))
    assert rejected.json()["total"] == len(REASONS) and len(rejected.json()["items"]) == 5
    assert client.get("/api/v1/flights?status=queued",
                      headers=auth(keys["viewer"])).json()["total"] == 0
    # the service still answers, and a corrected file for a rejected flight is accepted
    ok = post_parquet(client, keys["uploader"], make_parquet(aircraft, "R1", seed=2))
    assert ok.status_code == 202


@pytest.mark.parametrize(("path", "states"), [("/api/v1/flights", FlightStatus),
                                              ("/api/v1/jobs", JobStatus)])
def test_a_list_filters_on_exactly_the_statuses_of_the_vocabulary(
        client: TestClient, keys: dict[str, str], path: str, states: type) -> None:
    """The filter is derived from the enum: each value answers, anything else (another
    word, a member's name) is a 422 before any query."""
    viewer = auth(keys["viewer"])
    for state in states:
        assert client.get(path, params={"status": state.value}, headers=viewer).status_code == 200
    for other in ("lost", next(iter(states)).name, "queued|done"):
        assert client.get(path, params={"status": other}, headers=viewer).status_code == 422


def test_rejected_bytes_are_kept(client: TestClient, keys: dict[str, str], aircraft: str,
                                 app) -> None:  # type: ignore[no-untyped-def]
    data = make_parquet("GHOST", "X1")
    r = post_parquet(client, keys["uploader"], data)
    assert r.status_code == 422
    stored = client.get(f"/api/v1/flights/{r.json()['error']['details']['id']}",
                        headers=auth(keys["viewer"])).json()
    assert app.state.blobs.path_of(stored["sha256"]).read_bytes() == data
    # evaluated again and rejected again: the same row answers, no new row nor file
    again = post_parquet(client, keys["uploader"], data)
    details = again.json()["error"]["details"]
    assert again.status_code == 422 and details["duplicate"] is True
    assert details["id"] == stored["id"] and details["reasons"] == stored["reasons"]
    rows = client.get("/api/v1/flights?status=rejected", headers=auth(keys["viewer"])).json()
    assert rows["total"] == 1
    first = client.get(f"/api/v1/flights/{stored['id']}", headers=auth(keys["viewer"])).json()
    assert first["status"] == "rejected" and first["reasons"] == stored["reasons"]


def test_rejected_flight_is_ingested_once_its_aircraft_is_registered(
        client: TestClient, keys: dict[str, str], app) -> None:  # type: ignore[no-untyped-def]
    data = make_parquet("LATE1", "F0001")
    rejected = post_parquet(client, keys["uploader"], data)
    assert rejected.status_code == 422
    assert [x["code"] for x in rejected.json()["error"]["details"]["reasons"]] == [
        "unknown_aircraft"]
    r = client.post("/api/v1/aircraft", headers=auth(keys["admin"]), json={
        "tail": "LATE1", "base": "Turin", "actuators": serials_for("LATE1")})
    assert r.status_code == 201
    accepted = post_parquet(client, keys["uploader"], data)
    assert accepted.status_code == 202, accepted.text
    assert accepted.json()["status"] == "queued" and accepted.json()["duplicate"] is False
    again = post_parquet(client, keys["uploader"], data)  # now idempotent
    assert again.status_code == 200 and again.json()["duplicate"] is True
    assert again.json()["id"] == accepted.json()["id"]
    rows = client.get("/api/v1/flights?aircraft=LATE1", headers=auth(keys["viewer"])).json()
    assert sorted(f["status"] for f in rows["items"]) == ["queued", "rejected"]
    assert len({f["sha256"] for f in rows["items"]}) == 1  # one blob, content-addressed
    jobs = client.get("/api/v1/jobs", headers=auth(keys["viewer"])).json()
    assert [j["flight_id"] for j in jobs["items"]] == [accepted.json()["id"]]


def test_a_damaged_stored_copy_is_replaced_by_the_bytes_sent_again(
        client: TestClient, keys: dict[str, str], app) -> None:  # type: ignore[no-untyped-def]
    data = make_parquet("LATE2", "F0001")
    rejected = post_parquet(client, keys["uploader"], data)
    assert rejected.status_code == 422
    sha = client.get(rejected.json()["error"]["details"]["status_url"],
                     headers=auth(keys["viewer"])).json()["sha256"]
    app.state.blobs.path_of(sha).write_bytes(b"rotten")
    client.post("/api/v1/aircraft", headers=auth(keys["admin"]), json={
        "tail": "LATE2", "base": "Turin", "actuators": serials_for("LATE2")})
    assert post_parquet(client, keys["uploader"], data).status_code == 202
    assert app.state.blobs.path_of(sha).read_bytes() == data


def csv_bytes(log: FlightLog) -> bytes:
    names = list(log.channels)
    text = io.StringIO()
    np.savetxt(text, np.column_stack([log.channels[n] for n in names]), delimiter=",",
               header=",".join(names), comments="", fmt="%.9g")
    return text.getvalue().encode()


def post_csv(client: TestClient, key: str, data: bytes, form: dict[str, str]):  # type: ignore[no-untyped-def]
    return client.post("/api/v1/flights", headers=auth(key),
                       files={"file": ("flight.csv", data)}, data=form)


def test_csv_form_metadata_is_part_of_what_makes_an_upload_the_same(
        client: TestClient, keys: dict[str, str], aircraft: str) -> None:
    log = make_log(aircraft, "C1")
    data, form = csv_bytes(log), log.metadata.to_strings()
    first = post_csv(client, keys["uploader"], data, form)
    assert first.status_code == 202, first.text
    other_flight = post_csv(client, keys["uploader"], data, {**form, "flight": "C2"})
    assert other_flight.status_code == 202 and other_flight.json()["duplicate"] is False
    assert other_flight.json()["id"] != first.json()["id"]
    stored = client.get(other_flight.json()["status_url"], headers=auth(keys["viewer"])).json()
    assert stored["flight"] == "C2"
    # the same fields written another way are the same upload
    same = post_csv(client, keys["uploader"], data, {**form, "block_hours": "1.70"})
    assert same.status_code == 200 and same.json()["id"] == first.json()["id"]
    changed = post_csv(client, keys["uploader"], data, {**form, "block_hours": "2.5"})
    assert changed.status_code == 409 and changed.json()["error"]["code"] == "flight_exists"


def test_csv_rejected_for_a_form_field_is_accepted_with_the_field_corrected(
        client: TestClient, keys: dict[str, str], aircraft: str) -> None:
    log = make_log(aircraft, "C3")
    data, form = csv_bytes(log), log.metadata.to_strings()
    wrong = {**form, "actuator_serials": json.dumps({**serials_for(aircraft), "WT": "SN-X"})}
    rejected = post_csv(client, keys["uploader"], data, wrong)
    assert rejected.status_code == 422
    assert "serial_mismatch" in [x["code"] for x in rejected.json()["error"]["details"]["reasons"]]
    fixed = post_csv(client, keys["uploader"], data, form)
    assert fixed.status_code == 202 and fixed.json()["duplicate"] is False


def test_a_lost_race_answers_with_the_accepted_flight_of_the_same_upload(
        client: TestClient, keys: dict[str, str], aircraft: str, app) -> None:  # type: ignore[no-untyped-def]
    from server.services import flights as service

    data = make_parquet(aircraft, "F0009")
    accepted = post_parquet(client, keys["uploader"], data).json()
    rejected = post_parquet(client, keys["uploader"], make_parquet("GHOST", "F0009")).json()
    sha = client.get(accepted["status_url"], headers=auth(keys["viewer"])).json()["sha256"]
    ghost_sha = client.get(rejected["error"]["details"]["status_url"],
                           headers=auth(keys["viewer"])).json()["sha256"]
    with app.state.session_factory() as session:
        key = service.upload_key(sha256=sha, kind="parquet", form_metadata={})
        won = service.after_lost_race(session=session,
                                      race=service.LostRace(aircraft, "F0009", key))
        assert won.id == accepted["id"]
        ghost = service.upload_key(sha256=ghost_sha, kind="parquet", form_metadata={})
        with pytest.raises(service.LostRace):  # a rejected row is no earlier upload
            service.after_lost_race(session=session,
                                    race=service.LostRace("GHOST", "F0009", ghost))


def test_upload_errors_and_roles(client: TestClient, keys: dict[str, str], aircraft: str,
                                 settings) -> None:  # type: ignore[no-untyped-def]
    data = make_parquet(aircraft, "E1")
    assert client.post("/api/v1/flights", content=data, headers=PARQUET).status_code == 401
    for role in ("viewer", "operator"):
        assert post_parquet(client, keys[role], data).status_code == 403
    assert post_parquet(client, keys["admin"], data).status_code == 202
    wrong_type = client.post("/api/v1/flights", content=b"{}", headers={
        "Content-Type": "application/json", **auth(keys["uploader"])})
    assert wrong_type.status_code == 415
    assert wrong_type.json()["error"]["code"] == "unsupported_media_type"
    wrong_ext = client.post("/api/v1/flights", headers=auth(keys["uploader"]),
                            files={"file": ("flight.xlsx", b"PK..")})
    assert wrong_ext.status_code == 415
    no_file = client.post("/api/v1/flights", headers=auth(keys["uploader"]),
                          data={"aircraft": aircraft}, files={"other": ("a.csv", b"x")})
    assert no_file.status_code == 400
    assert client.get("/api/v1/flights/424242", headers=auth(keys["viewer"])).status_code == 404


@pytest.fixture
def small_limit_client(settings):  # type: ignore[no-untyped-def]
    from server.app import create_app

    app = create_app(settings.model_copy(update={"max_upload_bytes": 200_000}))
    with TestClient(app, raise_server_exceptions=False) as c:
        yield c, app
    app.state.engine.dispose()


def test_size_limit_413_streamed_and_declared(small_limit_client, keys) -> None:  # type: ignore[no-untyped-def]
    client, app = small_limit_client
    from server.auth import create_key
    from server.db import session_scope

    with session_scope(app.state.session_factory) as s:
        key = create_key(session=s, name="u", role="uploader")[1]
    big = b"\0" * 600_000
    declared = client.post("/api/v1/flights", content=big, headers={**PARQUET, **auth(key)})
    assert declared.status_code == 413
    assert declared.json()["error"]["code"] == "payload_too_large"

    def chunked():  # type: ignore[no-untyped-def]
        for _ in range(6):
            yield b"\0" * 100_000

    streamed = client.post("/api/v1/flights", content=chunked(), headers={**PARQUET, **auth(key)})
    assert streamed.status_code == 413
    # just over the file limit but within multipart overhead: refused by the spooler
    over = client.post("/api/v1/flights", content=b"\0" * 210_000,
                       headers={**PARQUET, **auth(key)})
    assert over.status_code == 413
    assert not any(app.state.settings.tmp_dir.iterdir())
    assert client.get("/api/v1/flights", headers=auth(key)).json()["total"] == 0


def test_openapi_documents_upload(client: TestClient, keys: dict[str, str]) -> None:
    spec = client.get("/openapi.json", headers=auth(keys["viewer"])).json()
    content = spec["paths"]["/api/v1/flights"]["post"]["requestBody"]["content"]
    assert {"application/vnd.apache.parquet", "multipart/form-data"} <= set(content)
    assert json.dumps(spec)  # serialisable


def test_signals_json_is_the_schema_pydantic_would_write() -> None:
    from server.schemas import SignalsRead
    from server.services.flights import signals_json

    arrays = {"t": np.array([0.0, 0.5]), "WL1.x": np.array([1.5, np.nan], dtype=np.float32),
              "WT.ia": np.array([np.inf, -2.25])}
    model = SignalsRead(flight_id=7, decimation=3, t=[0.0, 0.5],
                        channels={k: v.astype(float).tolist() for k, v in arrays.items()
                                  if k != "t"})
    assert json.loads(signals_json(7, 3, arrays)) == json.loads(model.model_dump_json())
    assert json.loads(signals_json(7, 3, arrays))["channels"]["WL1.x"] == [1.5, None]


def test_signal_reads_past_the_pool_and_its_queue_are_refused_busy() -> None:
    import asyncio
    import threading

    from server.boundedpool import BoundedPool
    from server.errors import ServiceUnavailable

    pool = BoundedPool("test", workers=1, waiting=1)
    release = threading.Event()

    async def three() -> list[object]:
        first = asyncio.ensure_future(pool.run(release.wait, 10))
        second = asyncio.ensure_future(pool.run(lambda: "waited"))
        await asyncio.sleep(0)  # both taken: one running, one waiting
        try:
            await pool.run(lambda: "never")
        except ServiceUnavailable as exc:
            refused: object = exc
        release.set()
        return [await first, await second, refused]

    try:
        first, second, refused = asyncio.run(three())
    finally:
        pool.shutdown()
    assert first is True and second == "waited"
    assert isinstance(refused, ServiceUnavailable) and refused.code == "busy"
    assert refused.headers == {"Retry-After": "2"}
