"""Idempotent audit appends: `audit_batches` records each keyed append transaction (its key,
the first entry it wrote and how many), in the same transaction as the entries. A retried
append with a committed key (a `authn check --cluster` partition re-run after its worker
died) finds the row and writes nothing. Append-only by trigger, like the other audit tables.

Revision 0004 (after 0003), 2026-11-23.
"""

import sqlalchemy as sa
from alembic import op

from registry.migrations.triggers import create_append_only, drop_append_only
from registry.models import UtcDateTime

revision = "0004"
down_revision = "0003"


def upgrade() -> None:
    create_append_only(
        op, "audit_batches",
        sa.Column("key", sa.String(200), nullable=False),
        sa.Column("first_seq", sa.BigInteger(), nullable=False),
        sa.Column("n", sa.Integer(), nullable=False),
        sa.Column("created_at", UtcDateTime(), nullable=False),
        sa.CheckConstraint("n >= 0", name=op.f("ck_audit_batches_n_non_negative")),
        sa.PrimaryKeyConstraint("key", name=op.f("pk_audit_batches")),
    )


def downgrade() -> None:
    drop_append_only(op, "audit_batches")
