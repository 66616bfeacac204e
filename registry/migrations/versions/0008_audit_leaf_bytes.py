"""Audit entries keep the bytes they are hashed over: `audit_log.leaf_bytes`.

From this revision the writer stores each entry's leaf bytes (authn.audit.leaf, version 1)
and every reader hashes what is stored. Existing entries get their version 0 bytes, the
canonical JSON the chain and leaf hashes were computed over (rebuilt here, frozen), so an
existing log keeps its hashes and its root. A row whose time is not in the stored form
keeps NULL: verify reports it as malformed, as before. The UPDATE trigger is dropped for
the backfill and recreated in the same transaction.
"""

import json
import re
from datetime import datetime, timezone

import sqlalchemy as sa
from alembic import op

from registry.migrations.triggers import append_only

revision = "0008"
down_revision = "0007"

_SQLITE_TIME = re.compile(r"\d{4}-\d{2}-\d{2} \d{2}:\d{2}:\d{2}\.\d{6}")


def _iso(value: object) -> str | None:
    """created_at as revisions 0001-0007 hashed it, or None for a value in no stored form."""
    if isinstance(value, str) and _SQLITE_TIME.fullmatch(value):
        return f"{value[:10]}T{value[11:]}+00:00"
    if isinstance(value, datetime) and value.tzinfo is not None:
        return value.astimezone(timezone.utc).isoformat(timespec="microseconds")
    return None


def _v0(seq: int, created_at: object, kind: object, serial: object, decision: object, payload: object,
        prev_hash: object) -> bytes | None:
    when = _iso(created_at)
    if when is None or not all(isinstance(x, str) for x in (kind, payload, prev_hash)):
        return None
    return json.dumps({"seq": int(seq), "created_at": when, "kind": kind, "serial": serial, "decision": decision,
                       "payload": payload, "prev_hash": prev_hash},
                      sort_keys=True, separators=(",", ":"), ensure_ascii=False, allow_nan=False).encode("utf-8")


def _no_update_trigger(dialect: str) -> None:
    for ddl in append_only("audit_log", dialect):
        if ddl.startswith("CREATE TRIGGER audit_log_no_update "):
            op.execute(ddl)


def _drop_no_update_trigger(dialect: str) -> None:
    if dialect == "postgresql":
        op.execute("DROP TRIGGER audit_log_no_update ON audit_log")
    elif dialect == "sqlite":
        op.execute("DROP TRIGGER audit_log_no_update")


def upgrade() -> None:
    bind = op.get_bind()
    dialect = bind.dialect.name
    op.add_column("audit_log", sa.Column("leaf_bytes", sa.LargeBinary(), nullable=True))
    _drop_no_update_trigger(dialect)
    last = None
    while True:
        rows = bind.execute(sa.text(
            "SELECT id, seq, created_at, kind, serial, decision, payload, prev_hash FROM audit_log "
            + ("" if last is None else "WHERE id > :last ") + "ORDER BY id LIMIT 5000"),
            {} if last is None else {"last": last}).all()
        if not rows:
            break
        filled = [{"id": r[0], "b": body} for r in rows if (body := _v0(*r[1:])) is not None]
        if filled:
            bind.execute(sa.text("UPDATE audit_log SET leaf_bytes = :b WHERE id = :id"), filled)
        last = rows[-1][0]
    _no_update_trigger(dialect)


def downgrade() -> None:
    """Refused while version 1 entries exist: their hashes cover bytes no column rebuilds."""
    bind = op.get_bind()
    dialect = bind.dialect.name
    first_byte = "substr(leaf_bytes, 1, 1) = X'01'" if dialect == "sqlite" else "get_byte(leaf_bytes, 0) = 1"
    if bind.execute(sa.text(f"SELECT COUNT(*) FROM audit_log WHERE {first_byte}")).scalar():
        raise RuntimeError("audit_log holds entries written with leaf bytes (version 1); refusing to drop them")
    _drop_no_update_trigger(dialect)
    op.execute("ALTER TABLE audit_log DROP COLUMN leaf_bytes")
    _no_update_trigger(dialect)
