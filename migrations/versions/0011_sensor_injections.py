"""test-station sensor injections and their ground truth

Revision ID: 0011
Revises: 0010
Create Date: 2026-12-05 01:00:00

``sensor_injections``: a degraded sensor (noise x F, LVDT offset drift per flight, a coarser
quantisation step) an operator injects into a simulated actuator, flown by the sim worker in
the loop; ``sensor_ground_truth``: what it applied to each flight (never in the flight log).
Both start empty.
"""

from alembic import op
import sqlalchemy as sa
import server.models


revision = '0011'
down_revision = '0010'
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        'sensor_injections',
        sa.Column('id', sa.Integer(), nullable=False),
        sa.Column('aircraft_id', sa.Integer(), nullable=False),
        sa.Column('position', sa.String(length=8), nullable=False),
        sa.Column('sensor', sa.String(length=16), nullable=False),
        sa.Column('kind', sa.String(length=16), nullable=False),
        sa.Column('value', sa.Float(), nullable=False),
        sa.Column('onset_flight', sa.Integer(), nullable=False),
        sa.Column('status', sa.String(length=16), nullable=False),
        sa.Column('started_flight', sa.Integer(), nullable=True),
        sa.Column('created_by', sa.String(length=128), nullable=False),
        sa.Column('created_at', server.models.UTCDateTime(timezone=True), nullable=False),
        sa.Column('cancelled_at', server.models.UTCDateTime(timezone=True), nullable=True),
        sa.ForeignKeyConstraint(['aircraft_id'], ['aircraft.id'],
                                name=op.f('fk_sensor_injections_aircraft_id_aircraft')),
        sa.PrimaryKeyConstraint('id', name=op.f('pk_sensor_injections')),
    )
    with op.batch_alter_table('sensor_injections', schema=None) as batch_op:
        batch_op.create_index(batch_op.f('ix_sensor_injections_aircraft_id'), ['aircraft_id'],
                              unique=False)
    op.create_table(
        'sensor_ground_truth',
        sa.Column('id', sa.Integer(), nullable=False),
        sa.Column('sensor_injection_id', sa.Integer(), nullable=False),
        sa.Column('flight_code', sa.String(length=64), nullable=False),
        sa.Column('flight_number', sa.Integer(), nullable=False),
        sa.Column('applied', sa.Float(), nullable=False),
        sa.Column('created_at', server.models.UTCDateTime(timezone=True), nullable=False),
        sa.ForeignKeyConstraint(
            ['sensor_injection_id'], ['sensor_injections.id'],
            name=op.f('fk_sensor_ground_truth_sensor_injection_id_sensor_injections')),
        sa.PrimaryKeyConstraint('id', name=op.f('pk_sensor_ground_truth')),
        sa.UniqueConstraint('sensor_injection_id', 'flight_code',
                            name='uq_sensor_ground_truth_injection_flight'),
    )
    with op.batch_alter_table('sensor_ground_truth', schema=None) as batch_op:
        batch_op.create_index(batch_op.f('ix_sensor_ground_truth_sensor_injection_id'),
                              ['sensor_injection_id'], unique=False)


def downgrade() -> None:
    with op.batch_alter_table('sensor_ground_truth', schema=None) as batch_op:
        batch_op.drop_index(batch_op.f('ix_sensor_ground_truth_sensor_injection_id'))
    op.drop_table('sensor_ground_truth')
    with op.batch_alter_table('sensor_injections', schema=None) as batch_op:
        batch_op.drop_index(batch_op.f('ix_sensor_injections_aircraft_id'))
    op.drop_table('sensor_injections')
