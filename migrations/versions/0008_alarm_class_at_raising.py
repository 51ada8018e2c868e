"""alarms: the class at raising; alarm events (later changes of the leading class)

Revision ID: 0008
Revises: 0007
Create Date: 2026-12-03 09:00:00

``alarms.raised_fault_mode`` is the leading fault class when the alarm was raised; it is never
rewritten (``alarms.fault_mode`` follows the evidence while the alarm is not closed). Existing
rows get their stored ``fault_mode``, the best that is known of them. ``alarm_events`` records
what happened to an alarm afterwards, one row each: ``class_change`` (``from_mode`` ->
``to_mode``) on the flight that changed the leading class.
"""

from alembic import op
import sqlalchemy as sa
import server.models


revision = '0008'
down_revision = '0007'
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table('alarms', schema=None) as batch_op:
        batch_op.add_column(sa.Column('raised_fault_mode', sa.String(length=16), nullable=True))
    op.execute("UPDATE alarms SET raised_fault_mode = fault_mode")
    op.create_table(
        'alarm_events',
        sa.Column('id', sa.Integer(), nullable=False),
        sa.Column('alarm_id', sa.Integer(), nullable=False),
        sa.Column('flight_id', sa.Integer(), nullable=True),
        sa.Column('flight_index', sa.Integer(), nullable=True),
        sa.Column('kind', sa.String(length=16), nullable=False),
        sa.Column('from_mode', sa.String(length=16), nullable=True),
        sa.Column('to_mode', sa.String(length=16), nullable=True),
        sa.Column('created_at', server.models.UTCDateTime(timezone=True), nullable=False),
        sa.ForeignKeyConstraint(['alarm_id'], ['alarms.id'],
                                name=op.f('fk_alarm_events_alarm_id_alarms')),
        sa.ForeignKeyConstraint(['flight_id'], ['flights.id'],
                                name=op.f('fk_alarm_events_flight_id_flights')),
        sa.PrimaryKeyConstraint('id', name=op.f('pk_alarm_events')),
    )
    with op.batch_alter_table('alarm_events', schema=None) as batch_op:
        batch_op.create_index(batch_op.f('ix_alarm_events_alarm_id'), ['alarm_id'], unique=False)


def downgrade() -> None:
    with op.batch_alter_table('alarm_events', schema=None) as batch_op:
        batch_op.drop_index(batch_op.f('ix_alarm_events_alarm_id'))
    op.drop_table('alarm_events')
    with op.batch_alter_table('alarms', schema=None) as batch_op:
        batch_op.drop_column('raised_fault_mode')
