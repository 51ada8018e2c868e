"""Bounded storage, in-process on SQLite and PostgreSQL: the per-key quota on kept rejected
flight logs (507 beyond it, with the file's reasons), identical re-uploads of a rejected flight
adding nothing, an admin freeing a key's quota, and ``GET /api/v1/storage`` (admin only)
against what is on disk. The 10 x 20 MiB junk probe on a live server:
tests/production/test_storage_bounds.py."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from server.app import create_app
from server.auth import create_key
from server.config import Settings
from server.db import session_scope
from server.models import ROLES
from server.services.storage import REJECTED_MIN_CHARGE
from tests.api.conftest import auth
from tests.flightlog_factory import make_parquet

PARQUET = {"Content-Type": "application/vnd.apache.parquet"}
KIB = 1024


def junk(size: int, seed: int) -> bytes:
    """Bytes no decoder reads: rejected as unreadable, kept for forensics."""
    return seed.to_bytes(4, "big") + os.urandom(size - 4)


def post(client: TestClient, key: str, data: bytes):  # type: ignore[no-untyped-def]
    return client.post("/api/v1/flights", content=data, headers={**PARQUET, **auth(key)})


def walk(root: Path) -> tuple[int, int]:
    """(files, bytes) under ``root``, independently of the service's own walk."""
    sizes = [p.lstat().st_size for p in root.rglob("*") if not p.is_dir() or p.is_symlink()]
    return len(sizes), sum(sizes)


@pytest.fixture
def quota_app(settings: Settings):  # type: ignore[no-untyped-def]
    """The app with a small quota (350 KiB) and a key per role."""
    app = create_app(settings.model_copy(update={"rejected_bytes_per_key": 350 * KIB}))
    with session_scope(app.state.session_factory) as s:
        keys = {r: create_key(session=s, name=f"q-{r}", role=r)[1] for r in ROLES}
        keys["uploader2"] = create_key(session=s, name="q-uploader2", role="uploader")[1]
    with TestClient(app) as client:
        yield app, client, keys
    app.state.engine.dispose()


def test_rejected_files_past_the_quota_are_refused_and_not_kept(quota_app) -> None:  # type: ignore[no-untyped-def]
    app, client, keys = quota_app
    blobs = app.state.settings.blob_dir
    files = [junk(100 * KIB, i) for i in range(5)]
    kept = [post(client, keys["uploader"], f) for f in files[:3]]
    assert [r.status_code for r in kept] == [422, 422, 422]
    assert walk(blobs) == (3, 300 * KIB)

    over = post(client, keys["uploader"], files[3])
    assert over.status_code == 507, over.text
    error = over.json()["error"]
    assert error["code"] == "rejected_quota_exceeded"
    assert "HMSM_REJECTED_BYTES_PER_KEY" in error["message"] and "not kept" in error["message"]
    assert error["details"]["quota_bytes"] == 350 * KIB
    assert error["details"]["stored_bytes"] == 300 * KIB
    assert error["details"]["file_bytes"] == 100 * KIB
    assert [r["code"] for r in error["details"]["reasons"]] == ["unreadable"]  # still told why
    assert walk(blobs) == (3, 300 * KIB)  # nothing kept
    assert not list(app.state.settings.tmp_dir.iterdir())  # nor left spooled
    rows = client.get("/api/v1/flights?status=rejected", headers=auth(keys["viewer"])).json()
    assert rows["total"] == 3

    # the same rejected upload again: the same row answers, nothing is charged or kept
    again = post(client, keys["uploader"], files[0])
    assert again.status_code == 422 and again.json()["error"]["details"]["duplicate"] is True
    assert again.json()["error"]["details"]["id"] == kept[0].json()["error"]["details"]["id"]
    # another key has its own quota; a good flight of the full key is still accepted
    assert post(client, keys["uploader2"], files[3]).status_code == 422
    client.post("/api/v1/aircraft", headers=auth(keys["admin"]), json={
        "tail": "Q1", "base": "Turin",
        "actuators": {"WL1": "SN-WL1-Q1", "WL2": "SN-WL2-Q1", "WT": "SN-WT-Q1"}})
    assert post(client, keys["uploader"], make_parquet("Q1", "F1")).status_code == 202

    # an admin deletes a rejected flight: its file goes, the key's quota is freed
    first = kept[0].json()["error"]["details"]
    sha = client.get(first["status_url"], headers=auth(keys["viewer"])).json()["sha256"]
    assert client.delete(f"/api/v1/flights/{first['id']}",
                         headers=auth(keys["uploader"])).status_code == 403
    assert client.delete(f"/api/v1/flights/{first['id']}",
                         headers=auth(keys["admin"])).status_code == 204
    assert not app.state.blobs.path_of(sha).exists()
    assert client.get(first["status_url"], headers=auth(keys["viewer"])).status_code == 404
    assert post(client, keys["uploader"], files[4]).status_code == 422


def test_an_accepted_flight_is_never_deleted(quota_app) -> None:  # type: ignore[no-untyped-def]
    _, client, keys = quota_app
    client.post("/api/v1/aircraft", headers=auth(keys["admin"]), json={
        "tail": "Q2", "base": "Turin",
        "actuators": {"WL1": "SN-WL1-Q2", "WL2": "SN-WL2-Q2", "WT": "SN-WT-Q2"}})
    r = post(client, keys["uploader"], make_parquet("Q2", "F1"))
    assert r.status_code == 202
    gone = client.delete(f"/api/v1/flights/{r.json()['id']}", headers=auth(keys["admin"]))
    assert gone.status_code == 409 and gone.json()["error"]["code"] == "not_rejected"
    assert client.delete("/api/v1/flights/424242", headers=auth(keys["admin"])).status_code == 404


def test_small_rejected_files_are_charged_at_least_the_minimum(settings: Settings) -> None:
    """Rows cost the database too (reasons up to 40 KB): tiny junk cannot make a key hold
    millions of rows within its bytes."""
    app = create_app(settings.model_copy(update={"rejected_bytes_per_key":
                                                 3 * REJECTED_MIN_CHARGE}))
    with session_scope(app.state.session_factory) as s:
        key = create_key(session=s, name="tiny", role="uploader")[1]
    with TestClient(app) as client:
        codes = [post(client, key, junk(16, i)).status_code for i in range(5)]
    app.state.engine.dispose()
    assert codes == [422, 422, 422, 507, 507]


def test_a_zero_quota_keeps_no_rejected_file(settings: Settings) -> None:
    app = create_app(settings.model_copy(update={"rejected_bytes_per_key": 0}))
    with session_scope(app.state.session_factory) as s:
        key = create_key(session=s, name="none", role="uploader")[1]
    with TestClient(app) as client:
        r = post(client, key, junk(1000, 1))
    app.state.engine.dispose()
    assert r.status_code == 507 and r.json()["error"]["details"]["reasons"]
    assert walk(app.state.settings.blob_dir) == (0, 0)


def test_storage_report_is_for_admins_only(client: TestClient, keys: dict[str, str]) -> None:
    assert client.get("/api/v1/storage").status_code == 401
    for role in set(ROLES) - {"admin"}:
        r = client.get("/api/v1/storage", headers=auth(keys[role]))
        assert r.status_code == 403 and r.json()["error"]["code"] == "forbidden", role
    assert client.get("/api/v1/storage", headers=auth(keys["admin"])).status_code == 200


def test_storage_report_matches_what_is_on_disk(app, client: TestClient, keys: dict[str, str],  # type: ignore[no-untyped-def]
                                                aircraft: str) -> None:
    settings: Settings = app.state.settings
    accepted = [make_parquet(aircraft, f"F{i}", seed=i) for i in range(2)]
    for data in accepted:
        assert post(client, keys["uploader"], data).status_code == 202
    ghost = make_parquet("GHOST", "G1")  # no such aircraft: rejected, kept
    assert post(client, keys["uploader"], ghost).status_code == 422
    rubbish = [junk(50 * KIB, i) for i in range(3)]
    for data in rubbish:
        assert post(client, keys["admin"], data).status_code == 422
    # what else lives in the data directory: a campaign, an evaluation report, a stray blob
    (settings.data_dir / "campaigns" / "c1" / "flights").mkdir(parents=True)
    (settings.data_dir / "campaigns" / "c1" / "flights" / "a.parquet").write_bytes(b"x" * 1000)
    (settings.data_dir / "campaigns" / "c1" / "manifest.json").write_bytes(b"{}")
    (settings.data_dir / "evaluation").mkdir()
    (settings.data_dir / "evaluation" / "latest.json").write_bytes(b"y" * 300)
    stray = settings.blob_dir / "ab" / "cd" / ("abcd" + "0" * 60)
    stray.parent.mkdir(parents=True)
    stray.write_bytes(b"z" * 777)

    report = client.get("/api/v1/storage", headers=auth(keys["admin"])).json()

    groups = {(g["state"], g["reason"]): g for g in report["flight_logs"]}
    assert groups[("accepted", "queued")] == {
        "state": "accepted", "reason": "queued", "flights": 2,
        "bytes": sum(len(d) for d in accepted)}
    assert groups[("rejected", "unknown_aircraft")]["bytes"] == len(ghost)
    assert groups[("rejected", "unreadable")] == {
        "state": "rejected", "reason": "unreadable", "flights": 3, "bytes": 3 * 50 * KIB}
    by_key = {k["key_name"]: k for k in report["rejected_by_key"]}
    assert by_key["test-admin"]["flights"] == 3 and by_key["test-admin"]["bytes"] == 150 * KIB
    assert by_key["test-uploader"]["charged_bytes"] == max(len(ghost), REJECTED_MIN_CHARGE)
    assert by_key["test-uploader"]["quota_bytes"] == settings.rejected_bytes_per_key

    blobs_on_disk = walk(settings.blob_dir)
    store = report["blob_store"]
    assert (store["files"], store["bytes"]) == blobs_on_disk
    assert (store["unreferenced_files"], store["unreferenced_bytes"]) == (1, 777)
    kept = sum(len(d) for d in [*accepted, ghost, *rubbish])
    assert (store["referenced_files"], store["referenced_bytes"]) == (6, kept)
    assert store["missing_files"] == 0

    files = {(f["kind"], f["name"]): f for f in report["files"]}
    assert (files[("blobs", None)]["files"], files[("blobs", None)]["bytes"]) == blobs_on_disk
    assert files[("campaign", "c1")] == {"kind": "campaign", "name": "c1", "files": 2,
                                         "bytes": 1002}
    assert files[("evaluation_reports", None)]["bytes"] == 300
    total_files, total_bytes = walk(settings.data_dir)
    assert report["data_dir"]["files"] == total_files
    assert sum(f["bytes"] for f in report["files"]) == report["data_dir"]["bytes"]
    # the SQLite file grows between the two walks (WAL): the rest must match to the byte
    database = files.get(("database", None), {"bytes": 0})["bytes"]
    db_on_disk = sum(p.stat().st_size for p in settings.data_dir.glob("hmsm.sqlite3*"))
    assert report["data_dir"]["bytes"] - database == total_bytes - db_on_disk
    if report["database"]["dialect"] == "postgresql":
        assert report["database"]["bytes"] > 0 and database == 0
