"""maintenance actions: the audit trail, deferrals, false-alarm resolutions, failed units

Revision ID: 0006
Revises: 0005
Create Date: 2026-12-01 23:50:00

``maintenance_actions`` is the per-actuator audit trail of replace / inspect (no fault found) /
defer, each with who, when and a work-order reference. Alarms gain how they were resolved
(``resolution``), the deferral they are held by (``deferred_until_flight``,
``deferred_until``) and the 5 % RUL quantile urgency is read from (``rul_low_flights``).
Actuators gain the failed state (``failed_at_flight``, ``failed_at``). All new columns are
nullable: existing rows need no value.
"""

from alembic import op
import sqlalchemy as sa
import server.models


revision = '0006'
down_revision = '0005'
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table('actuators', schema=None) as batch_op:
        batch_op.add_column(sa.Column('failed_at_flight', sa.Integer(), nullable=True))
        batch_op.add_column(sa.Column('failed_at', server.models.UTCDateTime(timezone=True),
                                      nullable=True))
    with op.batch_alter_table('alarms', schema=None) as batch_op:
        batch_op.add_column(sa.Column('rul_low_flights', sa.Float(), nullable=True))
        batch_op.add_column(sa.Column('resolution', sa.String(length=16), nullable=True))
        batch_op.add_column(sa.Column('deferred_until_flight', sa.Integer(), nullable=True))
        batch_op.add_column(sa.Column('deferred_until', server.models.UTCDateTime(timezone=True),
                                      nullable=True))
    op.create_table(
        'maintenance_actions',
        sa.Column('id', sa.Integer(), nullable=False),
        sa.Column('actuator_id', sa.Integer(), nullable=False),
        sa.Column('alarm_id', sa.Integer(), nullable=True),
        sa.Column('kind', sa.String(length=16), nullable=False),
        sa.Column('work_order', sa.String(length=32), nullable=False),
        sa.Column('performed_by', sa.String(length=128), nullable=False),
        sa.Column('key_id', sa.Integer(), nullable=True),
        sa.Column('performed_at', server.models.UTCDateTime(timezone=True), nullable=False),
        sa.Column('note', sa.Text(), nullable=True),
        sa.Column('new_actuator_id', sa.Integer(), nullable=True),
        sa.Column('new_serial', sa.String(length=64), nullable=True),
        sa.Column('closed_alarms', sa.Integer(), nullable=False),
        sa.Column('defer_until_flight', sa.Integer(), nullable=True),
        sa.Column('defer_until', server.models.UTCDateTime(timezone=True), nullable=True),
        sa.ForeignKeyConstraint(['actuator_id'], ['actuators.id'],
                                name=op.f('fk_maintenance_actions_actuator_id_actuators')),
        sa.ForeignKeyConstraint(['alarm_id'], ['alarms.id'],
                                name=op.f('fk_maintenance_actions_alarm_id_alarms')),
        sa.ForeignKeyConstraint(['key_id'], ['api_keys.id'],
                                name=op.f('fk_maintenance_actions_key_id_api_keys')),
        sa.ForeignKeyConstraint(['new_actuator_id'], ['actuators.id'],
                                name=op.f('fk_maintenance_actions_new_actuator_id_actuators')),
        sa.PrimaryKeyConstraint('id', name=op.f('pk_maintenance_actions')),
    )
    with op.batch_alter_table('maintenance_actions', schema=None) as batch_op:
        batch_op.create_index(batch_op.f('ix_maintenance_actions_actuator_id'), ['actuator_id'],
                              unique=False)
        batch_op.create_index(batch_op.f('ix_maintenance_actions_work_order'), ['work_order'],
                              unique=False)


def downgrade() -> None:
    with op.batch_alter_table('maintenance_actions', schema=None) as batch_op:
        batch_op.drop_index(batch_op.f('ix_maintenance_actions_work_order'))
        batch_op.drop_index(batch_op.f('ix_maintenance_actions_actuator_id'))
    op.drop_table('maintenance_actions')
    with op.batch_alter_table('alarms', schema=None) as batch_op:
        batch_op.drop_column('deferred_until')
        batch_op.drop_column('deferred_until_flight')
        batch_op.drop_column('resolution')
        batch_op.drop_column('rul_low_flights')
    with op.batch_alter_table('actuators', schema=None) as batch_op:
        batch_op.drop_column('failed_at')
        batch_op.drop_column('failed_at_flight')
