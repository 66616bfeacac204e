"""Idempotent audit appends: `audit_batches` records each keyed append transaction (its key,
the first entry it wrote and how many), in the same transaction as the entries. A retried
append with a committed key (a `authn check --cluster` partition re-run after its worker
died) finds the row and writes nothing. Append-only by trigger, like the other audit tables.

Revision ID: 0004
Revises: 0003
Create Date: 2026-11-23
"""

import sqlalchemy as sa
from alembic import op

from registry.migrations.triggers import append_only
from registry.models import UtcDateTime

revision = "0004"
down_revision = "0003"
branch_labels = None
depends_on = None

_TABLE = "audit_batches"


def upgrade() -> None:
    op.create_table(
        _TABLE,
        sa.Column("key", sa.String(200), nullable=False),
        sa.Column("first_seq", sa.BigInteger(), nullable=False),
        sa.Column("n", sa.Integer(), nullable=False),
        sa.Column("created_at", UtcDateTime(), nullable=False),
        sa.CheckConstraint("n >= 0", name=op.f("ck_audit_batches_n_non_negative")),
        sa.PrimaryKeyConstraint("key", name=op.f("pk_audit_batches")),
    )
    for ddl in append_only(_TABLE, op.get_bind().dialect.name):
        op.execute(ddl)


def downgrade() -> None:
    op.drop_table(_TABLE)  # its triggers go with it
    if op.get_bind().dialect.name == "postgresql":
        op.execute(f"DROP FUNCTION IF EXISTS {_TABLE}_append_only()")
