"""Audit log origins: `audit_log_meta` holds the log's name (its C2SP checkpoint origin,
written once by the first append under this revision), and `audit_tree_heads.origin` says
which log each head names (NULL for authn-sth/1 heads, which name none). Append-only by
trigger, like the other audit tables.

Revision ID: 0005
Revises: 0004
Create Date: 2026-11-26
"""

import sqlalchemy as sa
from alembic import op

revision = "0005"
down_revision = "0004"
branch_labels = None
depends_on = None

_TABLE = "audit_log_meta"


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
        sa.Column("name", sa.String(64), nullable=False),
        sa.Column("value", sa.Text(), nullable=False),
        sa.PrimaryKeyConstraint("name", name=op.f("pk_audit_log_meta")),
    )
    for ddl in _triggers(op.get_bind().dialect.name):
        op.execute(ddl)
    with op.batch_alter_table("audit_tree_heads") as batch:
        batch.add_column(sa.Column("origin", sa.Text(), nullable=True))


def downgrade() -> None:
    with op.batch_alter_table("audit_tree_heads") as batch:
        batch.drop_column("origin")
    op.drop_table(_TABLE)
    if op.get_bind().dialect.name == "postgresql":
        op.execute(f"DROP FUNCTION IF EXISTS {_TABLE}_append_only()")
