"""test station: the items' status held to StationStatus by a CHECK constraint

Revision ID: 0015
Revises: 0014
Create Date: 2026-12-06 10:00:00

``injections.status``, ``sensor_injections.status`` and ``sim_conditions.status`` were free
text kept right by the code alone; the database now refuses any other value
(``ck_<table>_status``). The values are ``server.vocabulary.StationStatus`` as of 0015, copied
here rather than imported, as in 0009; every value the code ever wrote is in them, so existing
rows pass. SQLite adds a constraint by rebuilding the table (batch mode), which would not carry
0013's partial unique index over faithfully: the index is dropped before and made again after.
"""

from alembic import op
import sqlalchemy as sa


revision = '0015'
down_revision = '0014'
branch_labels = None
depends_on = None

_STATUSES = ('pending', 'active', 'cancelled', 'failed')
_LIVE = "status IN ('pending', 'active')"
#: each table's one-live-item slot (0013's index, remade around the rebuild)
_SLOTS = {
    'injections': ('aircraft_id',),
    'sensor_injections': ('aircraft_id', 'position', 'sensor'),
    'sim_conditions': ('aircraft_id', 'kind'),
}


def _rebuild(table: str, change) -> None:  # type: ignore[no-untyped-def]
    op.drop_index(f'uq_{table}_live', table_name=table)
    with op.batch_alter_table(table, schema=None) as batch_op:
        change(batch_op)
    op.create_index(f'uq_{table}_live', table, list(_SLOTS[table]), unique=True,
                    sqlite_where=sa.text(_LIVE), postgresql_where=sa.text(_LIVE))


def upgrade() -> None:
    check = "status IN (" + ", ".join(f"'{v}'" for v in _STATUSES) + ")"
    for table in _SLOTS:
        _rebuild(table, lambda batch_op, table=table: batch_op.create_check_constraint(
            op.f(f'ck_{table}_status'), check))


def downgrade() -> None:
    for table in reversed(_SLOTS):
        _rebuild(table, lambda batch_op, table=table: batch_op.drop_constraint(
            op.f(f'ck_{table}_status'), type_='check'))
