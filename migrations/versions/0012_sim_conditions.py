"""test-station simulation conditions and their ground truth

Revision ID: 0012
Revises: 0011
Create Date: 2026-12-05 03:30:00

``sim_conditions``: a condition an operator sets on a simulated aircraft (ambient temperature
offset, load scale or offset, command scale, base), flown by the sim worker until cancelled;
``condition_ground_truth``: what it applied to each flight (never in the flight log). Both
start empty.
"""

import sqlalchemy as sa

from migrations.station_tables import create_item_tables, drop_item_tables


revision = '0012'
down_revision = '0011'
branch_labels = None
depends_on = None


def upgrade() -> None:
    create_item_tables('sim_conditions', [
        sa.Column('kind', sa.String(length=16), nullable=False),
        sa.Column('value', sa.Float(), nullable=True),
        sa.Column('base', sa.String(length=64), nullable=True),
    ], 'condition_ground_truth', 'condition_id',
                       'uq_condition_ground_truth_condition_flight')


def downgrade() -> None:
    drop_item_tables('sim_conditions', 'condition_ground_truth', 'condition_id')
