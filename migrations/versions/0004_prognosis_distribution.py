"""prognosis distribution: one RUL document per prediction

Revision ID: 0004
Revises: 0003
Create Date: 2026-12-01 20:45:00

Each prognosis keeps the filter's RulDistribution document (``distribution``) instead of five
columns in another shape (quantiles keyed by percent strings, p_fail_within, histogram,
severity mean and sd). Existing rows are converted both ways.
"""

from alembic import op
import sqlalchemy as sa


revision = '0004'
down_revision = '0003'
branch_labels = None
depends_on = None

_OLD = ('severity_mean', 'severity_std', 'rul_quantiles', 'p_fail_within', 'histogram')


def _table(*columns: sa.Column) -> sa.Table:
    return sa.table('prognoses', sa.column('id', sa.Integer), sa.column('flight_index', sa.Integer),
                    *columns)


def _to_document(row) -> dict:
    quantiles = sorted((float(k) / 100.0, v) for k, v in (row.rul_quantiles or {}).items())
    hist = row.histogram or {}
    return {"version": 1, "kind": "rul_distribution", "flight_index": row.flight_index,
            "quantiles": [[q, v] for q, v in quantiles],
            "mean": None,  # not kept by the old columns
            "p_fail_within": sorted([int(h), p] for h, p in (row.p_fail_within or {}).items()),
            "p_beyond_horizon": max(0.0, 1.0 - float(sum(hist.get("mass") or []))),
            "histogram_edges": list(hist.get("edges") or []),
            "histogram_mass": list(hist.get("mass") or []),
            "severity_mean": row.severity_mean, "severity_std": row.severity_std,
            "most_probable": None, "hours_per_flight": None}


def _from_document(doc: dict) -> dict:
    return {"severity_mean": doc.get("severity_mean") or 0.0,
            "severity_std": doc.get("severity_std") or 0.0,
            "rul_quantiles": {f"{100 * float(q):g}": v for q, v in doc.get("quantiles") or []},
            "p_fail_within": {str(h): p for h, p in doc.get("p_fail_within") or []},
            "histogram": {"edges": doc.get("histogram_edges") or [],
                          "mass": doc.get("histogram_mass") or []}}


def upgrade() -> None:
    with op.batch_alter_table('prognoses', schema=None) as batch_op:
        batch_op.add_column(sa.Column('distribution', sa.JSON(), nullable=True))
    conn = op.get_bind()
    old = _table(sa.column('severity_mean', sa.Float), sa.column('severity_std', sa.Float),
                 sa.column('rul_quantiles', sa.JSON), sa.column('p_fail_within', sa.JSON),
                 sa.column('histogram', sa.JSON), sa.column('distribution', sa.JSON))
    for row in conn.execute(sa.select(old)).all():
        conn.execute(old.update().where(old.c.id == row.id)
                     .values(distribution=_to_document(row)))
    with op.batch_alter_table('prognoses', schema=None) as batch_op:
        batch_op.alter_column('distribution', existing_type=sa.JSON(), nullable=False)
        for name in _OLD:
            batch_op.drop_column(name)


def downgrade() -> None:
    with op.batch_alter_table('prognoses', schema=None) as batch_op:
        batch_op.add_column(sa.Column('severity_mean', sa.Float(), nullable=True))
        batch_op.add_column(sa.Column('severity_std', sa.Float(), nullable=True))
        batch_op.add_column(sa.Column('rul_quantiles', sa.JSON(), nullable=True))
        batch_op.add_column(sa.Column('p_fail_within', sa.JSON(), nullable=True))
        batch_op.add_column(sa.Column('histogram', sa.JSON(), nullable=True))
    conn = op.get_bind()
    new = _table(sa.column('distribution', sa.JSON), sa.column('severity_mean', sa.Float),
                 sa.column('severity_std', sa.Float), sa.column('rul_quantiles', sa.JSON),
                 sa.column('p_fail_within', sa.JSON), sa.column('histogram', sa.JSON))
    for row in conn.execute(sa.select(new.c.id, new.c.distribution)).all():
        conn.execute(new.update().where(new.c.id == row.id)
                     .values(**_from_document(row.distribution or {})))
    with op.batch_alter_table('prognoses', schema=None) as batch_op:
        for name, kind in zip(_OLD, (sa.Float(), sa.Float(), sa.JSON(), sa.JSON(), sa.JSON()),
                              strict=True):
            batch_op.alter_column(name, existing_type=kind, nullable=False)
        batch_op.drop_column('distribution')
