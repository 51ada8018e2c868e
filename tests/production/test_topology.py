"""The production topology: the compose file is valid, and the same topology runs without
containers (API process + two worker processes + PostgreSQL on loopback) and analyses every
uploaded flight exactly once."""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import httpx
import pytest
from sqlalchemy import create_engine, func, select
from sqlalchemy.orm import Session

from server.config import Settings
from server.models import Flight, HealthRecord, Job
from tests.flightlog_factory import make_parquet, serials_for
from tests.live_server import running_server
from tests.production.helpers import (
    env_of,
    fresh_pg_database,
    seed_system,
    wait_until,
    worker_process,
)

ROOT = Path(__file__).resolve().parents[2]
PG_URL = os.environ.get("HMSM_TEST_POSTGRES_URL")
COMPOSE = shutil.which("docker-compose")


def _compose_config(env: dict[str, str], *args: str) -> subprocess.CompletedProcess[str]:
    assert COMPOSE
    clean = {k: v for k, v in os.environ.items()
             if not k.startswith(("POSTGRES_", "HMSM_SIM_", "COMPOSE_", "S3_"))}
    return subprocess.run([COMPOSE, "-f", str(ROOT / "docker-compose.yml"), *args, "config"],
                          env={**clean, **env}, capture_output=True, text=True, timeout=60,
                          cwd=ROOT)


@pytest.mark.skipif(COMPOSE is None, reason="docker-compose is not installed "
                    "(apt-get install -y docker-compose); the compose file is not validated")
def test_compose_file_is_valid_and_has_the_production_topology() -> None:
    yaml = pytest.importorskip("yaml")
    missing = _compose_config({})
    assert missing.returncode != 0 and "POSTGRES_PASSWORD" in missing.stderr

    done = _compose_config({"POSTGRES_PASSWORD": "s3cret-for-test"}, "--profile", "sim")
    assert done.returncode == 0, done.stderr
    config = yaml.safe_load(done.stdout)
    services = config["services"]
    assert {"postgres", "migrate", "api", "worker", "sim"} <= set(services)

    pg = services["postgres"]
    assert "pg_isready" in " ".join(pg["healthcheck"]["test"])
    assert any(":/var/lib/postgresql/data" in str(v) or
               (isinstance(v, dict) and v.get("target") == "/var/lib/postgresql/data")
               for v in pg["volumes"])

    assert services["migrate"]["command"] == ["hmsm", "db", "upgrade"]
    api = services["api"]
    assert api["command"][:2] == ["hmsm", "serve"] and "0.0.0.0" in api["command"]
    assert api["depends_on"]["migrate"]["condition"] == "service_completed_successfully"
    assert "/api/v1/health/ready" in " ".join(api["healthcheck"]["test"])

    worker = services["worker"]
    assert worker["command"][:2] == ["hmsm", "worker"]
    assert "container_name" not in worker and "ports" not in worker  # --scale worker=N works
    assert worker["depends_on"]["migrate"]["condition"] == "service_completed_successfully"

    sim = services["sim"]
    assert sim["profiles"] == ["sim"]
    command = " ".join(sim["command"])
    # the key is read from the environment, never on the command line (ps would show it)
    assert "sim-worker run --api http://api:8000" in command and "--key" not in command
    assert "HMSM_SIM_KEY:?" in command and "HMSM_SIM_KEY" in sim["environment"]

    for name in ("migrate", "api", "worker"):
        env = services[name]["environment"]
        assert env["HMSM_DATABASE_URL"].startswith("postgresql://hmsm:")
        assert env["HMSM_DATA_DIR"] == "/data"
    text = (ROOT / "docker-compose.yml").read_text()
    assert "s3cret" not in text and "${POSTGRES_PASSWORD:?" in text

    # flight logs in the object store: the API and the workers share no volume, only it
    s3 = services["seaweedfs"]
    entry = " ".join(s3["entrypoint"])
    assert "S3_ACCESS_KEY:?" in entry and "S3_SECRET_KEY:?" in entry and "-s3" in entry
    assert services["bucket"]["command"][:3] == ["hmsm", "store", "init"]
    assert services["bucket"]["depends_on"]["seaweedfs"]["condition"] == "service_healthy"
    assert int(worker["deploy"]["replicas"]) == 2 and "volumes" not in worker
    for name in ("api", "worker"):
        env = services[name]["environment"]
        assert env["HMSM_BLOB_URL"].startswith("s3://")
        assert env["HMSM_S3_ENDPOINT_URL"] == "http://seaweedfs:8333"
        assert env["AWS_SECRET_ACCESS_KEY"] == ""  # from .env, never a literal here
        assert services[name]["depends_on"]["bucket"]["condition"] == (
            "service_completed_successfully")

    # /metrics: the API reads the token from the secret Prometheus scrapes it with
    assert api["environment"]["HMSM_METRICS_TOKEN_FILE"] == "/run/secrets/metrics_token"
    assert "HMSM_METRICS_TOKEN" not in api["environment"]  # never a literal
    assert config["secrets"]["metrics_token"]["file"].endswith("secrets/metrics_token")
    prom = services["prometheus"]
    assert [s.get("source", s) if isinstance(s, dict) else s
            for s in prom["secrets"]] == ["metrics_token"]
    mounts = " ".join(str(v) for v in prom["volumes"])
    assert "deploy/prometheus/prometheus.yml:/etc/prometheus/prometheus.yml" in mounts
    assert any("retention.size" in arg for arg in prom["command"])
    assert prom["depends_on"]["api"]["condition"] == "service_healthy"
    assert all(str(p).startswith("127.0.0.1:") for p in prom["ports"]) or all(
        isinstance(p, dict) and p.get("host_ip") == "127.0.0.1" for p in prom["ports"])
    scrape = yaml.safe_load((ROOT / "deploy/prometheus/prometheus.yml").read_text())
    (job,) = scrape["scrape_configs"]
    assert job["metrics_path"] == "/metrics"
    assert job["authorization"] == {"type": "Bearer",
                                    "credentials_file": "/run/secrets/metrics_token"}
    assert job["dns_sd_configs"][0]["names"] == ["api"] and job["dns_sd_configs"][0][
        "port"] == 8000
    with_monitoring = _compose_config({"POSTGRES_PASSWORD": "x"}, "--profile", "monitoring")
    assert with_monitoring.returncode == 0, with_monitoring.stderr
    grafana = yaml.safe_load(with_monitoring.stdout)["services"]["grafana"]
    assert "GF_SECURITY_ADMIN_PASSWORD:?" in " ".join(grafana["entrypoint"])
    assert grafana["profiles"] == ["monitoring"]


def test_the_dashboard_and_alerts_use_only_metrics_the_service_exposes(tmp_path) -> None:
    """Every hmsm_ metric named in deploy/ (Grafana panels, Prometheus alerts) is one that
    /metrics serves, and the dashboard reads the data source the provisioning defines."""
    import json
    import re

    yaml = pytest.importorskip("yaml")
    from server.app import create_app
    from server.config import Settings

    app = create_app(Settings(data_dir=tmp_path / "data"))
    exposition = app.state.metrics.exposition().decode()
    app.state.engine.dispose()
    # a counter is typed under its name with _total in this format: one name per family
    exposed = {re.sub(r"_total$", "", n)
               for n in re.findall(r"^# TYPE (\S+) ", exposition, re.MULTILINE)}
    assert {"hmsm_job_stage_duration_seconds", "hmsm_queue_depth",
            "hmsm_worker_last_heartbeat_timestamp_seconds"} <= exposed

    def families(expr: str) -> set[str]:
        names = set(re.findall(r"\b((?:hmsm|process)_[a-z_]+)", expr))
        return {re.sub(r"_(bucket|sum|count|total)$", "", n) for n in names}

    dashboard = json.loads((ROOT / "deploy/grafana/hmsm.json").read_text())
    exprs = [t["expr"] for p in dashboard["panels"] for t in p.get("targets", [])]
    alerts = yaml.safe_load((ROOT / "deploy/prometheus/alerts.yml").read_text())
    exprs += [r["expr"] for g in alerts["groups"] for r in g["rules"]]
    used = set().union(*(families(e) for e in exprs))
    assert used and used <= exposed, used - exposed
    assert any("hmsm_job_stage_duration_seconds" in e for e in exprs)
    source = yaml.safe_load((ROOT / "deploy/grafana/provisioning/datasources/prometheus.yml")
                            .read_text())["datasources"][0]
    assert {p["datasource"]["uid"] for p in dashboard["panels"] if "datasource" in p} == {
        source["uid"]}


def test_dockerfile_runs_as_non_root_with_a_liveness_healthcheck() -> None:
    lines = [ln.strip() for ln in (ROOT / "Dockerfile").read_text().splitlines()
             if ln.strip() and not ln.strip().startswith("#")]
    assert lines[0] == "FROM python:3.11-slim"
    users = [ln.split()[1] for ln in lines if ln.startswith("USER ")]
    assert users and not users[-1].startswith(("root", "0"))
    joined = "\n".join(lines)
    assert "HEALTHCHECK" in joined and "/api/v1/health/live" in joined
    assert not any(word in joined.lower() for word in ("password=", "hmsm_key", "secret"))
    ignored = (ROOT / ".dockerignore").read_text().split()
    assert {".git", ".venv", ".env", "var"} <= set(ignored)


@pytest.mark.slow
@pytest.mark.postgres
@pytest.mark.skipif(not PG_URL, reason="HMSM_TEST_POSTGRES_URL not set")
def test_api_and_two_workers_on_postgres_analyse_every_flight_once(tmp_path,
                                                                   shipped_model) -> None:  # type: ignore[no-untyped-def]
    assert PG_URL
    tails, per_tail = ("TOPO1", "TOPO2", "TOPO3"), 4
    with fresh_pg_database(PG_URL) as db_url:
        settings = Settings(data_dir=tmp_path / "data", database_url=db_url)
        keys = seed_system(settings, shipped_model[0])
        admin = {"Authorization": f"Bearer {keys['admin']}"}
        up = {"Authorization": f"Bearer {keys['uploader']}",
              "Content-Type": "application/vnd.apache.parquet"}
        with running_server(env_of(settings), "--host", "127.0.0.1") as url, \
                worker_process(settings, "--concurrency", "2"), \
                httpx.Client(base_url=url, timeout=60) as http:
            for tail in tails:
                assert http.post("/api/v1/aircraft", headers=admin, json={
                    "tail": tail, "base": "Turin", "actuators": serials_for(tail)}
                ).status_code == 201
            for n in range(per_tail):
                for k, tail in enumerate(tails):
                    r = http.post("/api/v1/flights", headers=up,
                                  content=make_parquet(tail, f"F{n + 1:03d}", seed=10 * k + n))
                    assert r.status_code == 202, r.text

            def analysed() -> bool:
                page = http.get("/api/v1/flights?status=analyzed&limit=1", headers=admin)
                return page.json()["total"] == len(tails) * per_tail

            wait_until(analysed, 180, "every flight analysed", every_s=0.5)

        engine = create_engine(settings.effective_database_url)
        try:
            with Session(engine) as s:
                flights = s.scalars(select(Flight)).all()
                jobs = s.scalars(select(Job)).all()
                records = s.scalar(select(func.count()).select_from(HealthRecord))
        finally:
            engine.dispose()
        assert len(flights) == len(tails) * per_tail
        assert {f.status for f in flights} == {"analyzed"}
        assert len(jobs) == len(flights) and {j.status for j in jobs} == {"done"}
        assert records == 3 * len(flights)  # one per actuator and flight, none twice
