"""What ``GET /metrics`` shows, in the Prometheus text format (prometheus-client).

Two sources, both read at scrape time:

- this API process's own: request latency and count by route *template* (``/api/v1/flights/
  {flight_id}``, never the raw path, so that the label set stays bounded whatever clients
  send), upload sizes by outcome, and the process's CPU, memory and file descriptors;
- the database's, identical from every API process: queue depth and the age of the oldest
  queued job, running and dead jobs, job and stage durations, attempts by outcome and the
  workers' heartbeats (:mod:`server.services.telemetry`: workers may run on other hosts, so
  what they measure meets the API there, not in a shared file).

Each app has a registry of its own (tests build many apps in one process).
"""

from __future__ import annotations

import logging
import re
import time
from collections.abc import Iterable, Iterator
from typing import Any

from prometheus_client import (
    CollectorRegistry,
    Counter,
    Histogram,
    ProcessCollector,
    disable_created_metrics,
)
from prometheus_client.core import (
    CounterMetricFamily,
    GaugeMetricFamily,
    HistogramMetricFamily,
    Metric,
)
from prometheus_client.exposition import generate_latest
from prometheus_client.registry import Collector
from sqlalchemy.exc import SQLAlchemyError
from sqlalchemy.orm import Session, sessionmaker
from starlette.routing import Mount, compile_path
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from server.services import telemetry

__all__ = ["ServiceMetrics", "RequestMetricsMiddleware", "RouteTemplates", "UNMATCHED"]

log = logging.getLogger("hmsm.metrics")

#: the route label of a request no route matches (scanners' paths): one series for them all
UNMATCHED = "<unmatched>"
#: the methods that get a label of their own; any other word a client sends is "OTHER"
_METHODS = frozenset({"GET", "HEAD", "POST", "PUT", "PATCH", "DELETE", "OPTIONS"})
#: request latency buckets [s]: pages and reads in milliseconds, uploads in seconds
_LATENCY_S = (0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0, 10.0, 30.0, 60.0)
#: upload size buckets [B]: 64 KiB .. 64 MiB (the default body limit)
_UPLOAD_B = tuple(float(64 * 1024 * 4 ** i) for i in range(6))


class ServiceMetrics:
    """The registry of one app: its request and upload metrics, the process collector and
    the database collector."""

    def __init__(self, session_factory: sessionmaker[Session]):
        # no `_created` series beside each counter and histogram: Prometheus needs none of
        # them and they double what every scrape carries (a process-wide switch of the library)
        disable_created_metrics()
        self.registry = CollectorRegistry()
        self.latency = Histogram(
            "hmsm_http_request_duration_seconds", "Time from a request's arrival to the end of "
            "its response, by route template.", ["method", "route"], buckets=_LATENCY_S,
            registry=self.registry)
        self.requests = Counter(
            "hmsm_http_requests", "Requests answered, by route template and status code.",
            ["method", "route", "status"], registry=self.registry)
        self.uploads = Histogram(
            "hmsm_upload_bytes", "Flight-log uploads received in full, by outcome (accepted, "
            "duplicate, rejected, refused): sizes [B]; _sum is the bytes received.",
            ["outcome"], buckets=_UPLOAD_B, registry=self.registry)
        ProcessCollector(registry=self.registry)
        self.registry.register(DatabaseCollector(session_factory))

    def observe_request(self, method: str, route: str, status: int, seconds: float) -> None:
        method = method if method in _METHODS else "OTHER"
        self.latency.labels(method, route).observe(seconds)
        self.requests.labels(method, route, str(status)).inc()

    def observe_upload(self, outcome: str, size_bytes: int) -> None:
        self.uploads.labels(outcome).observe(size_bytes)

    def exposition(self) -> bytes:
        return generate_latest(self.registry)


class RouteTemplates:
    """The route templates of one app (``/api/v1/flights/{flight_id}``), registered with the
    routers it includes: a router's route objects and its prefix, which every FastAPI version
    has (whether the router keeps the included route or a copy with the full path differs
    between versions, and is not relied on)."""

    def __init__(self) -> None:
        self._by_route: dict[int, str] = {}
        self._patterns: list[tuple[re.Pattern[str], str]] = []

    def add_router(self, router: Any, prefix: str = "") -> None:
        for route in router.routes:
            path = prefix + str(route.path)
            self._by_route[id(route)] = path
            self._patterns.append((compile_path(path)[0], path))

    def add_mount(self, path: str) -> None:
        self._patterns.append((re.compile(re.escape(path) + "(/.*)?$"), f"{path}/{{path}}"))

    def of(self, scope: Scope) -> str:
        """The template of the route that served the request: the router's choice when it
        made one, else the first template its path matches (a request refused before
        routing, e.g. 413 by Content-Length or 429; a static file), else :data:`UNMATCHED`."""
        route = scope.get("route")
        if isinstance(route, Mount):
            return f"{route.path}/{{path}}"
        if route is not None:
            known = self._by_route.get(id(route))
            if known is not None:
                return known
            if isinstance(getattr(route, "path", None), str):  # a copy with its full path
                return str(route.path)
        path = scope.get("path", "")
        return next((t for pattern, t in self._patterns if pattern.match(path)), UNMATCHED)


class RequestMetricsMiddleware:
    """Times every HTTP request from its arrival to the end of its response (outermost, so
    that refusals by the other middlewares count too)."""

    def __init__(self, app: ASGIApp, metrics: ServiceMetrics, templates: RouteTemplates):
        self.app = app
        self.metrics = metrics
        self.templates = templates

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        start = time.perf_counter()
        status = 500  # what the client sees when the app raises before any response

        async def noting_send(message: Message) -> None:
            nonlocal status
            if message["type"] == "http.response.start":
                status = int(message["status"])
            await send(message)

        try:
            await self.app(scope, receive, noting_send)
        finally:
            self.metrics.observe_request(scope["method"], self.templates.of(scope), status,
                                         time.perf_counter() - start)


class DatabaseCollector(Collector):
    """The queue and the workers' telemetry, read from the database at each scrape. When the
    database does not answer, ``hmsm_telemetry_up`` is 0 and the rest of the scrape (this
    process's own metrics) is still served."""

    def __init__(self, session_factory: sessionmaker[Session]):
        self.factory = session_factory

    def collect(self) -> Iterator[Metric]:
        start = time.perf_counter()
        try:
            with self.factory() as session:
                data = telemetry.snapshot(session)
        except SQLAlchemyError:
            log.warning("metrics: the database did not answer", exc_info=True)
            data = None
        yield _gauge("hmsm_telemetry_up", "1 when this scrape read the queue and the workers' "
                     "telemetry from the database, 0 when it could not.", [],
                     [([], float(data is not None))])
        yield _gauge("hmsm_telemetry_read_seconds", "Time this scrape spent reading the "
                     "database.", [], [([], time.perf_counter() - start)])
        if data is not None:
            yield from _queue_metrics(data)
            yield from _job_metrics(data)
            yield from _worker_metrics(data)


def _gauge(name: str, doc: str, labels: list[str],
           values: Iterable[tuple[list[str], float]]) -> GaugeMetricFamily:
    family = GaugeMetricFamily(name, doc, labels=labels)
    for label_values, value in values:
        family.add_metric(label_values, value)
    return family


def _queue_metrics(data: telemetry.Telemetry) -> Iterator[Metric]:
    yield _gauge("hmsm_queue_depth", "Jobs waiting to be claimed (queued, due now or after a "
                 "retry's backoff).", ["kind"],
                 (([k], float(n)) for k, n in data.queue_depth.items()))
    yield _gauge("hmsm_queue_oldest_age_seconds", "Age of the oldest queued job (0: none "
                 "queued).", ["kind"], (([k], s) for k, s in data.oldest_queued_s.items()))
    yield _gauge("hmsm_jobs", "Jobs by status (queued, running, dead: given up, awaiting an "
                 "admin's retry).", ["kind", "status"],
                 (([k, s], float(n)) for (k, s), n in data.jobs.items()))


def _job_metrics(data: telemetry.Telemetry) -> Iterator[Metric]:
    whole = HistogramMetricFamily("hmsm_job_duration_seconds", "Duration of finished job "
                                  "attempts, by kind (measured by the workers).",
                                  labels=["kind"])
    stages = HistogramMetricFamily("hmsm_job_stage_duration_seconds", "Duration of each stage "
                                   "of finished analyses: decode, features, detection, "
                                   "classification, prognosis (measured by the workers).",
                                   labels=["kind", "stage"])
    for (kind, stage), hist in sorted(data.timings.items()):
        buckets = [(le, float(n)) for le, n in hist.buckets]
        if stage == telemetry.JOB:
            whole.add_metric([kind], buckets, hist.sum_s)
        else:
            stages.add_metric([kind, stage], buckets, hist.sum_s)
    yield whole
    yield stages
    attempts = CounterMetricFamily("hmsm_job_attempts", "Job attempts by how they ended: done, "
                                   "retried (failed, queued again), dead (failed, given up), "
                                   "deferred, abandoned (the worker vanished on the last).",
                                   labels=["kind", "outcome"])
    for (kind, outcome), n in sorted(data.attempts.items()):
        attempts.add_metric([kind, outcome], float(n))
    yield attempts


def _worker_metrics(data: telemetry.Telemetry) -> Iterator[Metric]:
    yield _gauge("hmsm_worker_last_heartbeat_timestamp_seconds", "Unix time of each running "
                 "worker's last heartbeat (every 10 s; a worker that died keeps its last for a "
                 "day).", ["worker", "host"],
                 (([w.worker_id, w.host], w.beat_at.timestamp()) for w in data.workers))
    yield _gauge("hmsm_worker_busy", "1 while the worker runs a job, at its last heartbeat.",
                 ["worker"], (([w.worker_id], float(w.job_id is not None))
                              for w in data.workers))
