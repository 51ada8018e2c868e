"""test-station injections: the planned failure flight; flights: raw-log retention

Revision ID: 0007
Revises: 0006
Create Date: 2026-12-02 07:00:00

``injections.planned_failure_flight`` is the flight a progressive injection is steered to fail
at (its start plus the requested or drawn time to failure), reported by the sim worker when the
injection goes active. Nullable: abrupt faults and older rows have none.
``flights.raw_pruned_at`` is when the retention of healthy flights removed the raw log
(``HMSM_RAW_RETENTION_HEALTHY``); null while the bytes are kept.
"""

from alembic import op
import sqlalchemy as sa
import server.models


revision = '0007'
down_revision = '0006'
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table('injections', schema=None) as batch_op:
        batch_op.add_column(sa.Column('planned_failure_flight', sa.Integer(), nullable=True))
    with op.batch_alter_table('flights', schema=None) as batch_op:
        batch_op.add_column(sa.Column('raw_pruned_at', server.models.UTCDateTime(timezone=True),
                                      nullable=True))


def downgrade() -> None:
    with op.batch_alter_table('flights', schema=None) as batch_op:
        batch_op.drop_column('raw_pruned_at')
    with op.batch_alter_table('injections', schema=None) as batch_op:
        batch_op.drop_column('planned_failure_flight')
