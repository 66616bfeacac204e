"""Audit log as a Merkle tree: per-entry leaf hashes, signed tree heads, recorded policies.

Existing entries keep their rows and chain; the migration computes each one's RFC 9162
leaf hash (SHA-256(0x00 || the canonical entry bytes that the chain hash already covers))
so that they become the first leaves of the tree. audit_log's UPDATE trigger is dropped
for the backfill and recreated in the same transaction. The new tables are append-only
by trigger, like audit_log.

Revision 0002 (after 0001), 2026-11-23.
"""

import hashlib
import json
from datetime import datetime, timezone

import sqlalchemy as sa
from alembic import op

from registry.migrations.triggers import append_only, drop_append_only, make_append_only
from registry.models import UtcDateTime

revision = "0002"
down_revision = "0001"

_NEW_TABLES = ("audit_policies", "audit_tree_heads")


def _iso(value: str | datetime) -> str:
    """created_at exactly as revision 0001's writer hashed it (frozen here)."""
    if isinstance(value, str):
        value = datetime.fromisoformat(value)
    value = value.replace(tzinfo=timezone.utc) if value.tzinfo is None else value.astimezone(timezone.utc)
    return value.isoformat(timespec="microseconds")


def _leaf_hash(seq: int, created_at: str | datetime, kind: str, serial: str | None, decision: str | None, payload: str,
               prev_hash: str) -> str:
    body = json.dumps({"seq": int(seq), "created_at": _iso(created_at), "kind": kind, "serial": serial,
                       "decision": decision, "payload": payload, "prev_hash": prev_hash},
                      sort_keys=True, separators=(",", ":"), ensure_ascii=False, allow_nan=False)
    return hashlib.sha256(b"\x00" + body.encode("utf-8")).hexdigest()


def _restore_no_update_trigger(dialect: str) -> None:
    """Recreate revision 0001's UPDATE trigger, dropped while leaf_hash is written or removed."""
    for ddl in append_only("audit_log", dialect):
        if ddl.startswith("CREATE TRIGGER audit_log_no_update "):
            op.execute(ddl)


def upgrade() -> None:
    bind = op.get_bind()
    dialect = bind.dialect.name
    op.add_column("audit_log", sa.Column("leaf_hash", sa.CHAR(64), nullable=True))
    op.create_table(
        "audit_policies",
        sa.Column("sha256", sa.CHAR(64), nullable=False),
        sa.Column("text", sa.Text(), nullable=False),
        sa.Column("first_seen", UtcDateTime(), nullable=False),
        sa.PrimaryKeyConstraint("sha256", name=op.f("pk_audit_policies")),
    )
    op.create_table(
        "audit_tree_heads",
        sa.Column("id", sa.Integer(), autoincrement=True, nullable=False),
        sa.Column("tree_size", sa.BigInteger(), nullable=False),
        sa.Column("timestamp_ms", sa.BigInteger(), nullable=False),
        sa.Column("root_hash", sa.CHAR(64), nullable=False),
        sa.Column("log_key_id", sa.CHAR(64), nullable=False),
        sa.Column("signature", sa.Text(), nullable=False),
        sa.Column("frontier", sa.Text(), nullable=True),  # stored on periodic heads only
        sa.PrimaryKeyConstraint("id", name=op.f("pk_audit_tree_heads")),
    )
    op.create_index(op.f("ix_audit_tree_heads_tree_size"), "audit_tree_heads", ["tree_size"])

    # backfill leaf hashes of the entries written before this revision
    if dialect == "postgresql":
        op.execute("DROP TRIGGER audit_log_no_update ON audit_log")
    elif dialect == "sqlite":
        op.execute("DROP TRIGGER audit_log_no_update")
    last = None
    while True:
        rows = bind.execute(sa.text(
            "SELECT id, seq, created_at, kind, serial, decision, payload, prev_hash FROM audit_log "
            + ("" if last is None else "WHERE id > :last ") + "ORDER BY id LIMIT 5000"),
            {} if last is None else {"last": last}).all()
        if not rows:
            break
        bind.execute(sa.text("UPDATE audit_log SET leaf_hash = :h WHERE id = :id"),
                     [{"id": r[0], "h": _leaf_hash(*r[1:])} for r in rows])
        last = rows[-1][0]
    _restore_no_update_trigger(dialect)
    for table in _NEW_TABLES:
        make_append_only(op, table)


def downgrade() -> None:
    dialect = op.get_bind().dialect.name
    op.drop_index(op.f("ix_audit_tree_heads_tree_size"), table_name="audit_tree_heads")
    for table in reversed(_NEW_TABLES):
        drop_append_only(op, table)
    if dialect == "postgresql":
        op.execute("DROP TRIGGER audit_log_no_update ON audit_log")
    elif dialect == "sqlite":
        op.execute("DROP TRIGGER audit_log_no_update")
    op.execute("ALTER TABLE audit_log DROP COLUMN leaf_hash")  # in place: keeps the other triggers
    _restore_no_update_trigger(dialect)
