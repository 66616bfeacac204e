"""Audit log origins: `audit_log_meta` holds the log's name (its C2SP checkpoint origin,
written once by the first append under this revision), and `audit_tree_heads.origin` says
which log each head names (NULL for authn-sth/1 heads, which name none). Append-only by
trigger, like the other audit tables.

Revision 0005 (after 0004), 2026-11-26.
"""

import sqlalchemy as sa
from alembic import op

from registry.migrations.triggers import create_append_only, drop_append_only

revision = "0005"
down_revision = "0004"


def upgrade() -> None:
    create_append_only(
        op, "audit_log_meta",
        sa.Column("name", sa.String(64), nullable=False),
        sa.Column("value", sa.Text(), nullable=False),
        sa.PrimaryKeyConstraint("name", name=op.f("pk_audit_log_meta")),
    )
    with op.batch_alter_table("audit_tree_heads") as batch:
        batch.add_column(sa.Column("origin", sa.Text(), nullable=True))


def downgrade() -> None:
    with op.batch_alter_table("audit_tree_heads") as batch:
        batch.drop_column("origin")
    drop_append_only(op, "audit_log_meta")
