"""The two tables of a test-station kind that records the value it applied to each flight (a
sensor injection, a condition), as migrations 0011 and 0012 made them.

Frozen with those revisions: it builds their schema, so a later change to these tables is a new
migration, never an edit here.
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

import server.models

__all__ = ["create_item_tables", "drop_item_tables"]


def create_item_tables(table: str, columns: list[sa.Column], truth: str, item_key: str,
                       truth_unique: str) -> None:
    """``table`` (an item on an aircraft with its own ``columns``) and ``truth`` (its applied
    value per flight, naming the item by ``item_key``), each with its index."""
    op.create_table(
        table,
        sa.Column('id', sa.Integer(), nullable=False),
        sa.Column('aircraft_id', sa.Integer(), nullable=False),
        *columns,
        sa.Column('onset_flight', sa.Integer(), nullable=False),
        sa.Column('status', sa.String(length=16), nullable=False),
        sa.Column('started_flight', sa.Integer(), nullable=True),
        sa.Column('created_by', sa.String(length=128), nullable=False),
        sa.Column('created_at', server.models.UTCDateTime(timezone=True), nullable=False),
        sa.Column('cancelled_at', server.models.UTCDateTime(timezone=True), nullable=True),
        sa.ForeignKeyConstraint(['aircraft_id'], ['aircraft.id'],
                                name=op.f(f'fk_{table}_aircraft_id_aircraft')),
        sa.PrimaryKeyConstraint('id', name=op.f(f'pk_{table}')),
    )
    with op.batch_alter_table(table, schema=None) as batch_op:
        batch_op.create_index(batch_op.f(f'ix_{table}_aircraft_id'), ['aircraft_id'],
                              unique=False)
    op.create_table(
        truth,
        sa.Column('id', sa.Integer(), nullable=False),
        sa.Column(item_key, sa.Integer(), nullable=False),
        sa.Column('flight_code', sa.String(length=64), nullable=False),
        sa.Column('flight_number', sa.Integer(), nullable=False),
        sa.Column('applied', sa.Float(), nullable=False),
        sa.Column('created_at', server.models.UTCDateTime(timezone=True), nullable=False),
        sa.ForeignKeyConstraint([item_key], [f'{table}.id'],
                                name=op.f(f'fk_{truth}_{item_key}_{table}')),
        sa.PrimaryKeyConstraint('id', name=op.f(f'pk_{truth}')),
        sa.UniqueConstraint(item_key, 'flight_code', name=truth_unique),
    )
    with op.batch_alter_table(truth, schema=None) as batch_op:
        batch_op.create_index(batch_op.f(f'ix_{truth}_{item_key}'), [item_key], unique=False)


def drop_item_tables(table: str, truth: str, item_key: str) -> None:
    with op.batch_alter_table(truth, schema=None) as batch_op:
        batch_op.drop_index(batch_op.f(f'ix_{truth}_{item_key}'))
    op.drop_table(truth)
    with op.batch_alter_table(table, schema=None) as batch_op:
        batch_op.drop_index(batch_op.f(f'ix_{table}_aircraft_id'))
    op.drop_table(table)
