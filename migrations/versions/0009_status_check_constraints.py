"""flight and job statuses: CHECK constraints on their vocabulary

Revision ID: 0009
Revises: 0008
Create Date: 2026-12-05 09:00:00

``flights.status`` and ``jobs.status`` were free text kept right by the code alone; the
database now refuses any other value (``ck_flights_status``, ``ck_jobs_status``). The values
are ``server.vocabulary.FlightStatus`` and ``JobStatus`` as of 0009, copied here rather than
imported: a migration must build the same schema whatever the enums become later. Every value
the code ever wrote is in them, so existing rows pass.
"""

from alembic import op


revision = '0009'
down_revision = '0008'
branch_labels = None
depends_on = None

_STATUSES = {
    'flights': ('received', 'queued', 'analyzing', 'analyzed', 'rejected', 'failed'),
    'jobs': ('queued', 'running', 'done', 'dead'),
}


def _one_of(values: tuple[str, ...]) -> str:
    return "status IN (" + ", ".join(f"'{v}'" for v in values) + ")"


def upgrade() -> None:
    for table, values in _STATUSES.items():
        # SQLite cannot add a constraint in place: batch mode rebuilds the table with it
        with op.batch_alter_table(table, schema=None) as batch_op:
            batch_op.create_check_constraint(op.f(f'ck_{table}_status'), _one_of(values))


def downgrade() -> None:
    for table in reversed(_STATUSES):
        with op.batch_alter_table(table, schema=None) as batch_op:
            batch_op.drop_constraint(op.f(f'ck_{table}_status'), type_='check')
