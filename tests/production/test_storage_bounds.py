"""The outside probe of issue 43 against a live ``hmsm serve`` (SQLite and PostgreSQL): one
key sends 10 junk files of 20 MiB. Before the quota all 10 were answered 422 and kept (200 MB
in 1.8 s); now the key's kept rejected bytes stop at ``HMSM_REJECTED_BYTES_PER_KEY`` (default
128 MiB: 6 files), the rest are answered 507 ``rejected_quota_exceeded`` and leave nothing,
sending one of them again adds no row, and ``GET /api/v1/storage`` says what is on disk."""

from __future__ import annotations

import os
import time

import httpx
import pytest

from server.config import Settings
from server.services.storage import REJECTED_MIN_CHARGE
from tests.live_server import running_server
from tests.production.helpers import env_of, seed_system

pytestmark = pytest.mark.slow

MIB = 1024 * 1024
PARQUET = "application/vnd.apache.parquet"
DEFAULT_QUOTA = Settings().rejected_bytes_per_key


def _tree_bytes(root) -> int:  # type: ignore[no-untyped-def]
    return sum(p.stat().st_size for p in root.rglob("*") if p.is_file())


def test_junk_probe_stops_at_the_quota_and_disk_use_stays_bounded(settings: Settings) -> None:
    keys = seed_system(settings)
    up = {"Authorization": f"Bearer {keys['uploader']}", "Content-Type": PARQUET}
    blob_dir = settings.blob_dir
    probe = [os.urandom(20 * MIB) for _ in range(10)]
    with running_server(env_of(settings)) as url, httpx.Client(base_url=url, timeout=120) as http:
        start = time.monotonic()
        answers = [http.post("/api/v1/flights", content=data, headers=up) for data in probe]
        took = time.monotonic() - start
        codes = [r.status_code for r in answers]
        kept = DEFAULT_QUOTA // (20 * MIB)
        assert codes == [422] * kept + [507] * (10 - kept), codes
        refusal = answers[-1].json()["error"]
        assert refusal["code"] == "rejected_quota_exceeded"
        assert "HMSM_REJECTED_BYTES_PER_KEY" in refusal["message"]
        assert refusal["details"]["stored_bytes"] == kept * 20 * MIB
        assert refusal["details"]["reasons"][0]["code"] == "unreadable"
        on_disk = _tree_bytes(blob_dir)
        assert on_disk == kept * 20 * MIB <= DEFAULT_QUOTA
        assert not any(settings.tmp_dir.iterdir())

        # the same junk again, kept or refused before: no new row, no new file
        for data in (probe[0], probe[0], probe[-1]):
            again = http.post("/api/v1/flights", content=data, headers=up)
            assert again.status_code in (422, 507)
        admin = {"Authorization": f"Bearer {keys['admin']}"}
        rejected = http.get("/api/v1/flights?status=rejected", headers=admin).json()["total"]
        assert rejected == kept and _tree_bytes(blob_dir) == on_disk

        report = http.get("/api/v1/storage", headers=admin).json()
        assert report["flight_logs"] == [{"state": "rejected", "reason": "unreadable",
                                          "flights": kept, "bytes": on_disk}]
        assert report["blob_store"]["bytes"] == on_disk
        assert report["blob_store"]["referenced_files"] == kept
        (usage,) = report["rejected_by_key"]
        assert usage["key_name"] == "prod-uploader" and usage["bytes"] == on_disk
        assert usage["charged_bytes"] == kept * max(20 * MIB, REJECTED_MIN_CHARGE)
        for role in ("viewer", "uploader", "operator", "maintainer"):
            refused = http.get("/api/v1/storage",
                               headers={"Authorization": f"Bearer {keys[role]}"})
            assert refused.status_code == 403, role
    print(f"\nprobe: {codes.count(422)} x 422, {codes.count(507)} x 507 in {took:.1f} s; "
          f"blobs on disk {on_disk / MIB:.0f} MiB; data dir "
          f"{_tree_bytes(settings.data_dir) / MIB:.0f} MiB")
