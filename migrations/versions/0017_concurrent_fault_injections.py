"""test station: concurrent fault injections, one live per mode of each actuator

Revision ID: 0017
Revises: 0016
Create Date: 2026-12-06 16:00:00

The simulator flies several faults at once: on other actuators of the aircraft, or other modes
on one actuator. A fault injection's slot (0013: the aircraft) becomes the aircraft, position
and mode: the partial unique index ``uq_injections_live`` over the live rows (``status``
pending or active; copied here, not imported, as in 0013) is made again over
``(aircraft_id, position, fault_mode)``. Every database at 0016 takes it (its live injections
are at most one per aircraft). A downgrade to one live injection per aircraft cannot take a
database holding more: it stops before changing anything and names them, for an operator to
cancel all but one.
"""

from alembic import op
import sqlalchemy as sa


revision = '0017'
down_revision = '0016'
branch_labels = None
depends_on = None

_LIVE = "status IN ('pending', 'active')"
_INDEX = 'uq_injections_live'
_PER_MODE = ('aircraft_id', 'position', 'fault_mode')
_PER_AIRCRAFT = ('aircraft_id',)


def _slot_index(columns: tuple[str, ...]) -> None:
    op.create_index(_INDEX, 'injections', list(columns), unique=True,
                    sqlite_where=sa.text(_LIVE), postgresql_where=sa.text(_LIVE))


def upgrade() -> None:
    op.drop_index(_INDEX, table_name='injections')
    _slot_index(_PER_MODE)


def downgrade() -> None:
    rows = op.get_bind().execute(sa.text(
        f"SELECT aircraft_id, COUNT(*) FROM injections WHERE {_LIVE} GROUP BY aircraft_id "
        "HAVING COUNT(*) > 1 ORDER BY aircraft_id")).all()
    if rows:
        named = ", ".join(f"aircraft {r[0]}: {r[1]}" for r in rows)
        raise RuntimeError(f"injections: more than one live injection on an aircraft ({named}); "
                           "one fault at a time before 0017: cancel all but one on each, then "
                           "downgrade again")
    op.drop_index(_INDEX, table_name='injections')
    _slot_index(_PER_AIRCRAFT)
