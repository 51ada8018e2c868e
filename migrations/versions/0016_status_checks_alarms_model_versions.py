"""alarm and model-version statuses: CHECK constraints on their vocabulary

Revision ID: 0016
Revises: 0015
Create Date: 2026-12-06 10:00:00

``alarms.status`` and ``model_versions.status`` were free text kept right by the code alone;
the database now refuses any other value (``ck_alarms_status``, ``ck_model_versions_status``),
as 0009 did for flights and jobs. The values are ``server.vocabulary.AlarmStatus`` and
``ModelVersionStatus`` as of 0016, copied here rather than imported (a migration must build
the same schema whatever the enums become). Every value the code ever wrote is in them; a
database holding another (written by hand) cannot take the constraint: the upgrade stops
before changing anything and names those rows, for an operator to correct them.
"""

from alembic import op
import sqlalchemy as sa


revision = '0016'
down_revision = '0015'
branch_labels = None
depends_on = None

_STATUSES = {
    'alarms': ('open', 'acknowledged', 'closed'),
    'model_versions': ('training', 'ready', 'failed'),
}
#: rows named in the error at most (the count says how many there are)
_NAMED = 20


def _one_of(values: tuple[str, ...]) -> str:
    return "status IN (" + ", ".join(f"'{v}'" for v in values) + ")"


def _outside(table: str, values: tuple[str, ...]) -> str | None:
    """What is wrong in ``table`` for its constraint (its rows by id and status), or None."""
    rows = op.get_bind().execute(sa.text(
        f"SELECT id, status FROM {table} WHERE NOT ({_one_of(values)}) ORDER BY id")).all()
    if not rows:
        return None
    named = ", ".join(f"{row.id}: {row.status!r}" for row in rows[:_NAMED])
    more = f" and {len(rows) - _NAMED} more" if len(rows) > _NAMED else ""
    return f"{table}: {len(rows)} rows with a status outside {values} (id: status {named}{more})"


def upgrade() -> None:
    problems = [p for t, v in _STATUSES.items() if (p := _outside(t, v)) is not None]
    if problems:  # all checked before any table is touched
        raise RuntimeError("; ".join(problems) + "; set them to one of the statuses, then "
                           "upgrade again")
    for table, values in _STATUSES.items():
        # SQLite cannot add a constraint in place: batch mode rebuilds the table with it
        with op.batch_alter_table(table, schema=None) as batch_op:
            batch_op.create_check_constraint(op.f(f'ck_{table}_status'), _one_of(values))


def downgrade() -> None:
    for table in reversed(_STATUSES):
        with op.batch_alter_table(table, schema=None) as batch_op:
            batch_op.drop_constraint(op.f(f'ck_{table}_status'), type_='check')
