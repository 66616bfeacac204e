"""API keys of `authn serve`: one row per key, only its SHA-256 stored (the token is 32
random bytes, so a fast hash is enough), revocation kept as a time, never a deletion.

The audit log gains the entry kind 'registry' (a registry change made through the API,
naming the acting key). Widening a CHECK needs a table rebuild on SQLite: the rows are
copied unchanged (hashes cover their bytes, not their rowids) and the append-only triggers
are recreated in the same transaction.

Revision 0003 (after 0002), 2026-11-23.
"""

import sqlalchemy as sa
from alembic import op

from registry.migrations.triggers import make_append_only
from registry.models import UtcDateTime

revision = "0003"
down_revision = "0002"


_OLD_KINDS = "kind IN ('decision', 'error')"
_NEW_KINDS = "kind IN ('decision', 'error', 'registry')"


def _audit_kinds(old: str, new: str) -> None:
    bind = op.get_bind()
    if bind.dialect.name == "postgresql":
        op.execute("ALTER TABLE audit_log DROP CONSTRAINT ck_audit_log_kind_enum")
        op.execute(f"ALTER TABLE audit_log ADD CONSTRAINT ck_audit_log_kind_enum CHECK ({new})")
        return
    if bind.dialect.name != "sqlite":
        return
    (ddl,) = bind.execute(sa.text("SELECT sql FROM sqlite_master WHERE type = 'table' AND name = 'audit_log'")).one()
    if old not in ddl:
        raise RuntimeError(f"audit_log's kind CHECK is not {old!r}; refusing to rebuild the table")
    indexes = [r[0] for r in bind.execute(sa.text(
        "SELECT sql FROM sqlite_master WHERE type = 'index' AND tbl_name = 'audit_log' AND sql IS NOT NULL"))]
    op.execute(ddl.replace(old, new).replace("audit_log", "audit_log_rebuilt", 1))
    op.execute("INSERT INTO audit_log_rebuilt SELECT * FROM audit_log")
    op.execute("DROP TABLE audit_log")  # its triggers go with it; DROP fires no DELETE trigger
    op.execute("ALTER TABLE audit_log_rebuilt RENAME TO audit_log")
    for sql in indexes:
        op.execute(sql)
    make_append_only(op, "audit_log")


def upgrade() -> None:
    op.create_table(
        "api_keys",
        sa.Column("id", sa.Integer(), autoincrement=True, nullable=False),
        sa.Column("name", sa.String(100), nullable=True),
        sa.Column("role", sa.String(16), nullable=False),
        sa.Column("key_hash", sa.CHAR(64), nullable=False),
        sa.Column("created_at", UtcDateTime(), nullable=False),
        sa.Column("revoked_at", UtcDateTime(), nullable=True),
        sa.CheckConstraint("role IN ('operator', 'admin')", name=op.f("ck_api_keys_role_enum")),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_api_keys")),
        sa.UniqueConstraint("key_hash", name=op.f("uq_api_keys_key_hash")),
    )
    _audit_kinds(_OLD_KINDS, _NEW_KINDS)


def downgrade() -> None:
    op.drop_table("api_keys")
    _audit_kinds(_NEW_KINDS, _OLD_KINDS)  # fails (CHECK) while 'registry' entries exist: they are kept
