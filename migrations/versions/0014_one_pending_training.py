"""jobs: one pending training at a time, held by the database

Revision ID: 0014
Revises: 0013
Create Date: 2026-12-06 09:00:00

``POST /models/train`` queued any number of ``train_model`` jobs (each may simulate a quick
design campaign of about 920 flights); the service now refuses a second while one is queued or
running (409), by a check before the insert that two concurrent requests could both pass. A
partial unique index over the pending training jobs (the condition copied here, not imported,
as in 0009) makes the database refuse the second. An existing database may hold several
pending ones (what the old endpoint allowed, and no API cancels a job): the earliest keeps the
slot, the other queued ones are made ``dead`` and their model versions ``failed``, each with
the reason, as the new endpoint would have refused them; running ones are never touched (two
running at once cannot be: they share one lock key, and with it a migration would stop).
"""

import json

from alembic import op
import sqlalchemy as sa


revision = '0014'
down_revision = '0013'
branch_labels = None
depends_on = None

_PENDING = "kind = 'train_model' AND status IN ('queued', 'running')"
_REASON = ("Refused when the database was upgraded to one pending training at a time "
           "(migration 0014): job {keep} held the slot. Request it again once that is done.")


def _bury_surplus() -> None:
    bind = op.get_bind()
    pending = bind.execute(sa.text(
        f"SELECT id, status, payload FROM jobs WHERE {_PENDING} ORDER BY id")).all()
    if len(pending) < 2:
        return
    running = [row.id for row in pending if row.status == 'running']
    if len(running) > 1:
        raise RuntimeError(f"jobs: training jobs {running} are all running; stop the workers "
                           "and let their leases run out, then upgrade again")
    keep = running[0] if running else pending[0].id
    reason = _REASON.format(keep=keep)
    for row in pending:
        if row.id == keep:
            continue
        bind.execute(sa.text(
            "UPDATE jobs SET status = 'dead', last_error = :reason, finished_at = "
            "CURRENT_TIMESTAMP, updated_at = CURRENT_TIMESTAMP WHERE id = :id"),
            {"reason": reason, "id": row.id})
        payload = row.payload if isinstance(row.payload, dict) else json.loads(row.payload)
        if payload.get("version_id") is not None:
            bind.execute(sa.text(
                "UPDATE model_versions SET status = 'failed', error = :reason, finished_at = "
                "CURRENT_TIMESTAMP WHERE id = :id AND status = 'training'"),
                {"reason": reason, "id": int(payload["version_id"])})


def upgrade() -> None:
    _bury_surplus()
    op.create_index('uq_jobs_pending_training', 'jobs', ['kind'], unique=True,
                    sqlite_where=sa.text(_PENDING), postgresql_where=sa.text(_PENDING))


def downgrade() -> None:
    op.drop_index('uq_jobs_pending_training', table_name='jobs')
