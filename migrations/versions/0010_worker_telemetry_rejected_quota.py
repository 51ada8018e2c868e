"""worker telemetry for /metrics; the index the rejected-bytes quota reads

Revision ID: 0010
Revises: 0009
Create Date: 2026-12-08 09:00:00

Workers are separate processes, possibly on other hosts without a shared filesystem, so what
they measure reaches the API's /metrics through the database: ``worker_heartbeats`` (one row
per running worker: its last beat and current job), ``job_timings`` (the buckets of the job
and stage duration histograms, added to by each finished job: a bounded table, kinds x stages
x buckets) and ``job_attempts`` (attempts by kind and outcome). They start empty: nothing of
the past is known. ``ix_flights_uploader_status`` serves the per-key quota on stored rejected
bytes, summed before each rejected file is kept.
"""

from alembic import op
import sqlalchemy as sa
import server.models


revision = '0010'
down_revision = '0009'
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        'worker_heartbeats',
        sa.Column('worker_id', sa.String(length=128), nullable=False),
        sa.Column('host', sa.String(length=255), nullable=False),
        sa.Column('pid', sa.Integer(), nullable=False),
        sa.Column('started_at', server.models.UTCDateTime(timezone=True), nullable=False),
        sa.Column('beat_at', server.models.UTCDateTime(timezone=True), nullable=False),
        sa.Column('job_id', sa.Integer(), nullable=True),
        sa.PrimaryKeyConstraint('worker_id', name=op.f('pk_worker_heartbeats')),
    )
    op.create_table(
        'job_timings',
        sa.Column('kind', sa.String(length=32), nullable=False),
        sa.Column('stage', sa.String(length=32), nullable=False),
        sa.Column('le', sa.String(length=24), nullable=False),
        sa.Column('observations', sa.BigInteger(), nullable=False),
        sa.Column('seconds', sa.Float(), nullable=False),
        sa.PrimaryKeyConstraint('kind', 'stage', 'le', name=op.f('pk_job_timings')),
    )
    op.create_table(
        'job_attempts',
        sa.Column('kind', sa.String(length=32), nullable=False),
        sa.Column('outcome', sa.String(length=16), nullable=False),
        sa.Column('attempts', sa.BigInteger(), nullable=False),
        sa.PrimaryKeyConstraint('kind', 'outcome', name=op.f('pk_job_attempts')),
    )
    with op.batch_alter_table('flights', schema=None) as batch_op:
        batch_op.create_index('ix_flights_uploader_status', ['uploader_key_id', 'status'],
                              unique=False)


def downgrade() -> None:
    with op.batch_alter_table('flights', schema=None) as batch_op:
        batch_op.drop_index('ix_flights_uploader_status')
    op.drop_table('job_attempts')
    op.drop_table('job_timings')
    op.drop_table('worker_heartbeats')
