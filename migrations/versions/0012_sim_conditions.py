"""test-station simulation conditions and their ground truth

Revision ID: 0012
Revises: 0011
Create Date: 2026-12-05 03:30:00

``sim_conditions``: a condition an operator sets on a simulated aircraft (ambient temperature
offset, load scale or offset, command scale, base), flown by the sim worker until cancelled;
``condition_ground_truth``: what it applied to each flight (never in the flight log). Both
start empty.
"""

from alembic import op
import sqlalchemy as sa
import server.models


revision = '0012'
down_revision = '0011'
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        'sim_conditions',
        sa.Column('id', sa.Integer(), nullable=False),
        sa.Column('aircraft_id', sa.Integer(), nullable=False),
        sa.Column('kind', sa.String(length=16), nullable=False),
        sa.Column('value', sa.Float(), nullable=True),
        sa.Column('base', sa.String(length=64), nullable=True),
        sa.Column('onset_flight', sa.Integer(), nullable=False),
        sa.Column('status', sa.String(length=16), nullable=False),
        sa.Column('started_flight', sa.Integer(), nullable=True),
        sa.Column('created_by', sa.String(length=128), nullable=False),
        sa.Column('created_at', server.models.UTCDateTime(timezone=True), nullable=False),
        sa.Column('cancelled_at', server.models.UTCDateTime(timezone=True), nullable=True),
        sa.ForeignKeyConstraint(['aircraft_id'], ['aircraft.id'],
                                name=op.f('fk_sim_conditions_aircraft_id_aircraft')),
        sa.PrimaryKeyConstraint('id', name=op.f('pk_sim_conditions')),
    )
    with op.batch_alter_table('sim_conditions', schema=None) as batch_op:
        batch_op.create_index(batch_op.f('ix_sim_conditions_aircraft_id'), ['aircraft_id'],
                              unique=False)
    op.create_table(
        'condition_ground_truth',
        sa.Column('id', sa.Integer(), nullable=False),
        sa.Column('condition_id', sa.Integer(), nullable=False),
        sa.Column('flight_code', sa.String(length=64), nullable=False),
        sa.Column('flight_number', sa.Integer(), nullable=False),
        sa.Column('applied', sa.Float(), nullable=False),
        sa.Column('created_at', server.models.UTCDateTime(timezone=True), nullable=False),
        sa.ForeignKeyConstraint(
            ['condition_id'], ['sim_conditions.id'],
            name=op.f('fk_condition_ground_truth_condition_id_sim_conditions')),
        sa.PrimaryKeyConstraint('id', name=op.f('pk_condition_ground_truth')),
        sa.UniqueConstraint('condition_id', 'flight_code',
                            name='uq_condition_ground_truth_condition_flight'),
    )
    with op.batch_alter_table('condition_ground_truth', schema=None) as batch_op:
        batch_op.create_index(batch_op.f('ix_condition_ground_truth_condition_id'),
                              ['condition_id'], unique=False)


def downgrade() -> None:
    with op.batch_alter_table('condition_ground_truth', schema=None) as batch_op:
        batch_op.drop_index(batch_op.f('ix_condition_ground_truth_condition_id'))
    op.drop_table('condition_ground_truth')
    with op.batch_alter_table('sim_conditions', schema=None) as batch_op:
        batch_op.drop_index(batch_op.f('ix_sim_conditions_aircraft_id'))
    op.drop_table('sim_conditions')
