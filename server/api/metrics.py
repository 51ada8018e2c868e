"""``GET /metrics``: the service's own performance in the Prometheus text format
(:mod:`server.metrics`), for the metrics token or an admin key (docs/PRODUCTION.md)."""

from __future__ import annotations

from fastapi import APIRouter, Request
from fastapi.responses import Response
from prometheus_client.exposition import CONTENT_TYPE_LATEST

from server.api.deps import MetricsReader

router = APIRouter(tags=["operations"])


@router.get("/metrics", include_in_schema=False)
def metrics(request: Request, _: MetricsReader) -> Response:
    # a sync route: the database part of the scrape runs on the thread pool, off the loop
    return Response(request.app.state.metrics.exposition(), media_type=CONTENT_TYPE_LATEST)
