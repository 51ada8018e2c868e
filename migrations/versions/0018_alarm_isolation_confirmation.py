"""alarms: the ambiguity group of an alarm and its confirmed class

Revision ID: 0018
Revises: 0017
Create Date: 2026-12-06 18:00:00

An alarm names the units it may belong to with the probability of each (``isolation``): its own
unit alone, or both winglet drives when it rests on a feature the partner drive moves too. Its
class is provisional at the alarm and confirmed later (``confirmed_fault_mode``). Both columns
are nullable: alarms raised before have none (the pages and the API show them as their unit's,
their class as it stands).
A plain ADD / DROP COLUMN on both databases (SQLite has had DROP COLUMN since 3.35), so the
table's constraints are not copied around.
"""

from alembic import op
import sqlalchemy as sa


revision = '0018'
down_revision = '0017'
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.add_column('alarms', sa.Column('isolation', sa.JSON(), nullable=True))
    op.add_column('alarms', sa.Column('confirmed_fault_mode', sa.String(length=16),
                                      nullable=True))


def downgrade() -> None:
    op.drop_column('alarms', 'confirmed_fault_mode')
    op.drop_column('alarms', 'isolation')
