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

from registry.migrations.triggers import replace_in_table
from registry.models import UtcDateTime

revision = "0003"
down_revision = "0002"


_OLD_KINDS = "kind IN ('decision', 'error')"
_NEW_KINDS = "kind IN ('decision', 'error', 'registry')"


def _audit_kinds(old: str, new: str) -> None:
    replace_in_table(op, "audit_log", [(old, new)], "ck_audit_log_kind_enum")


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
