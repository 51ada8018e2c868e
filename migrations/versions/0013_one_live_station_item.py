"""test station: one live item per slot, held by the database

Revision ID: 0013
Revises: 0012
Create Date: 2026-12-05 09:00:00

A fault injection per aircraft, a sensor injection per aircraft, position and sensor, a
condition per aircraft and kind: the services refuse a second live one (409) by a check before
the insert, which two concurrent requests could both pass. Partial unique indexes over the live
rows (``status`` pending or active; copied here, not imported, as in 0009) make the database
refuse the second. An existing database holding two live items in one slot cannot take the
index: the upgrade stops and names them, for an operator to cancel one.
"""

from alembic import op
import sqlalchemy as sa


revision = '0013'
down_revision = '0012'
branch_labels = None
depends_on = None

_LIVE = "status IN ('pending', 'active')"
_SLOTS = {
    'injections': ('aircraft_id',),
    'sensor_injections': ('aircraft_id', 'position', 'sensor'),
    'sim_conditions': ('aircraft_id', 'kind'),
}


def _check_no_duplicates(table: str, columns: tuple[str, ...]) -> None:
    cols = ", ".join(columns)
    rows = op.get_bind().execute(sa.text(
        f"SELECT {cols}, COUNT(*) FROM {table} WHERE {_LIVE} GROUP BY {cols} "
        "HAVING COUNT(*) > 1")).all()
    if rows:
        raise RuntimeError(f"{table}: more than one live item in the slots {rows} "
                           f"({cols}, count); cancel all but one, then upgrade again")


def upgrade() -> None:
    for table, columns in _SLOTS.items():  # all checked before any index is made
        _check_no_duplicates(table, columns)
    for table, columns in _SLOTS.items():
        op.create_index(f'uq_{table}_live', table, list(columns), unique=True,
                        sqlite_where=sa.text(_LIVE), postgresql_where=sa.text(_LIVE))


def downgrade() -> None:
    for table in reversed(_SLOTS):
        op.drop_index(f'uq_{table}_live', table_name=table)
