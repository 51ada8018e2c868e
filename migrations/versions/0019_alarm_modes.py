"""alarms: the modes present on the alarm's unit, each with its own probability and RUL

Revision ID: 0019
Revises: 0018
Create Date: 2026-12-06 21:00:00

Two degradations can run on one unit at once: an alarm names its leading mode
(``fault_mode``) and every mode present (``modes``: a list of ``{mode, probability,
rul_median_flights}``, the leading one first), updated while the alarm is open. Nullable:
alarms raised before have none (the pages and the API show their leading mode alone).
A plain ADD / DROP COLUMN on both databases.
"""

from alembic import op
import sqlalchemy as sa


revision = '0019'
down_revision = '0018'
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.add_column('alarms', sa.Column('modes', sa.JSON(), nullable=True))


def downgrade() -> None:
    op.drop_column('alarms', 'modes')
