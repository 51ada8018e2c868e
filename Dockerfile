# EMA health-management service (HMSM): one image for the API, the analysis workers, the
# migration job and the simulated half-wing (sim-worker). No secrets are baked in: every
# setting comes from the environment at run time (see docker-compose.yml, docs/PRODUCTION.md).
FROM python:3.11-slim

ENV PYTHONDONTWRITEBYTECODE=1 \
    PYTHONUNBUFFERED=1 \
    PIP_NO_CACHE_DIR=1 \
    PIP_DISABLE_PIP_VERSION_CHECK=1 \
    HMSM_DATA_DIR=/data \
    HMSM_HOST=0.0.0.0 \
    HMSM_PORT=8000 \
    NUMBA_CACHE_DIR=/tmp/numba-cache

# An unprivileged user owns only the data directory.
RUN groupadd --system --gid 10001 hmsm \
    && useradd --system --uid 10001 --gid hmsm --home-dir /app --shell /usr/sbin/nologin hmsm \
    && mkdir -p /app /data \
    && chown hmsm:hmsm /data

WORKDIR /app
COPY pyproject.toml README.md alembic.ini ./
COPY server ./server
COPY sim_worker ./sim_worker
COPY web ./web
COPY migrations ./migrations
RUN pip install --no-compile . \
    && rm -rf /root/.cache

USER hmsm:hmsm
VOLUME ["/data"]
EXPOSE 8000

# Liveness only (the process answers); readiness (database + schema) is checked by compose.
HEALTHCHECK --interval=15s --timeout=5s --start-period=30s --retries=3 \
    CMD ["python", "-c", "import sys, urllib.request; sys.exit(0 if urllib.request.urlopen('http://127.0.0.1:8000/api/v1/health/live', timeout=4).status == 200 else 1)"]

CMD ["hmsm", "serve", "--host", "0.0.0.0", "--port", "8000"]
