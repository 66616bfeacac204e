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

from registry.models import UtcDateTime

revision = "0004"
down_revision = "0003"
branch_labels = None
depends_on = None

_TABLE = "audit_batches"


def _triggers(dialect: str) -> list[str]:
    if dialect == "sqlite":
        return [f"CREATE TRIGGER {_TABLE}_no_{op_} BEFORE {op_.upper()} ON {_TABLE} "
                f"BEGIN SELECT RAISE(ABORT, '{_TABLE} is append-only'); END" for op_ in ("update", "delete")]
    if dialect != "postgresql":
        return []
    fn = f"{_TABLE}_append_only"
    return [f"CREATE FUNCTION {fn}() RETURNS trigger LANGUAGE plpgsql AS $$ "
            f"BEGIN RAISE EXCEPTION '{_TABLE} is append-only'; END; $$",
            f"CREATE TRIGGER {_TABLE}_no_update BEFORE UPDATE ON {_TABLE} FOR EACH ROW EXECUTE FUNCTION {fn}()",
            f"CREATE TRIGGER {_TABLE}_no_delete BEFORE DELETE ON {_TABLE} FOR EACH ROW EXECUTE FUNCTION {fn}()",
            f"CREATE TRIGGER {_TABLE}_no_truncate BEFORE TRUNCATE ON {_TABLE} "
            f"FOR EACH STATEMENT EXECUTE FUNCTION {fn}()"]


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
    for ddl in _triggers(op.get_bind().dialect.name):
        op.execute(ddl)


def downgrade() -> None:
    op.drop_table(_TABLE)  # its triggers go with it
    if op.get_bind().dialect.name == "postgresql":
        op.execute(f"DROP FUNCTION IF EXISTS {_TABLE}_append_only()")
