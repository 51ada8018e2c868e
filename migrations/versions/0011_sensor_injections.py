"""test-station sensor injections and their ground truth

Revision ID: 0011
Revises: 0010
Create Date: 2026-12-05 01:00:00

``sensor_injections``: a degraded sensor (noise x F, LVDT offset drift per flight, a coarser
quantisation step) an operator injects into a simulated actuator, flown by the sim worker in
the loop; ``sensor_ground_truth``: what it applied to each flight (never in the flight log).
Both start empty.
"""

import sqlalchemy as sa

from migrations.station_tables import create_item_tables, drop_item_tables


revision = '0011'
down_revision = '0010'
branch_labels = None
depends_on = None


def upgrade() -> None:
    create_item_tables('sensor_injections', [
        sa.Column('position', sa.String(length=8), nullable=False),
        sa.Column('sensor', sa.String(length=16), nullable=False),
        sa.Column('kind', sa.String(length=16), nullable=False),
        sa.Column('value', sa.Float(), nullable=False),
    ], 'sensor_ground_truth', 'sensor_injection_id',
                       'uq_sensor_ground_truth_injection_flight')


def downgrade() -> None:
    drop_item_tables('sensor_injections', 'sensor_ground_truth', 'sensor_injection_id')
