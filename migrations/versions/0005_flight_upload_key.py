"""flight upload key: idempotency on (aircraft, flight, bytes), not bytes alone

Revision ID: 0005
Revises: 0004
Create Date: 2026-12-01 21:30:00

``flights.sha256`` stays the content hash but is no longer unique: the same bytes may be sent
again after a rejection (a new row, evaluated afresh) or, for CSV/MAT, under other form
metadata (another flight). ``upload_key`` (SHA-256 over kind, content hash and the metadata
sent beside the bytes) is unique among flights that are not rejected. Existing rows get their
key from what they stored: Parquet rows from kind and hash alone; CSV/MAT rows with their
stored metadata, which is the parsed form metadata for every row that could be decoded.

Downgrade restores the unique content hash, and refuses while several flights share one.
"""

import hashlib
import json

from alembic import op
import sqlalchemy as sa


revision = '0005'
down_revision = '0004'
branch_labels = None
depends_on = None

_ACCEPTED = sa.text("status <> 'rejected'")


def _upload_key(kind: str, sha256: str, metadata: dict) -> str:
    # A frozen copy of server.models.upload_key_of (and its rule for stored rows) as of 0005.
    outside = {} if kind == 'parquet' else {str(k): str(v) for k, v in metadata.items()}
    text = json.dumps([kind, sha256, outside], sort_keys=True, separators=(',', ':'))
    return hashlib.sha256(text.encode()).hexdigest()


def _as_dict(value) -> dict:
    if isinstance(value, str):
        value = json.loads(value)
    return value if isinstance(value, dict) else {}


def upgrade() -> None:
    with op.batch_alter_table('flights', schema=None) as batch_op:
        batch_op.add_column(sa.Column('upload_key', sa.String(length=64), nullable=True))
    conn = op.get_bind()
    flights = sa.table('flights', sa.column('id', sa.Integer), sa.column('sha256', sa.String),
                       sa.column('content_kind', sa.String),
                       sa.column('flight_metadata', sa.JSON),
                       sa.column('upload_key', sa.String))
    for row in conn.execute(sa.select(flights)).all():
        key = _upload_key(row.content_kind, row.sha256, _as_dict(row.flight_metadata))
        conn.execute(flights.update().where(flights.c.id == row.id).values(upload_key=key))
    with op.batch_alter_table('flights', schema=None) as batch_op:
        batch_op.alter_column('upload_key', existing_type=sa.String(length=64), nullable=False)
        batch_op.drop_constraint('uq_flights_sha256', type_='unique')
        batch_op.create_index(batch_op.f('ix_flights_sha256'), ['sha256'], unique=False)
        batch_op.create_index('uq_flights_accepted_upload_key', ['upload_key'], unique=True,
                              sqlite_where=_ACCEPTED, postgresql_where=_ACCEPTED)


def downgrade() -> None:
    conn = op.get_bind()
    shared = conn.execute(sa.text(
        'SELECT COUNT(*) FROM (SELECT sha256 FROM flights GROUP BY sha256 '
        'HAVING COUNT(*) > 1) AS shared')).scalar_one()
    if shared:
        raise RuntimeError(
            f'0005 cannot be undone: {shared} content hash(es) are shared by several flights '
            '(re-sent after a rejection, or CSV/MAT bytes under other metadata), and 0004 '
            'requires one flight per hash. Remove the extra rows first.')
    with op.batch_alter_table('flights', schema=None) as batch_op:
        batch_op.drop_index('uq_flights_accepted_upload_key', sqlite_where=_ACCEPTED,
                            postgresql_where=_ACCEPTED)
        batch_op.drop_index(batch_op.f('ix_flights_sha256'))
        batch_op.create_unique_constraint('uq_flights_sha256', ['sha256'])
        batch_op.drop_column('upload_key')
