"""Audit entries: the entry the product records (`NewEntry`), the entry read back
(`Entry`), and reading them: filtered lists, one entry, a batch by its idempotency key, the
recorded policy texts. What an entry's leaf bytes are: authn.audit.leaf.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit, urlunsplit

from authn.audit._internal.rows import COLUMNS
from core.errors import SystemFault
from registry.dbapi import Database

GENESIS = "0" * 64

_PG_AUDIT_LOCK = 0x61756469_746C6F67  # "auditlog"

@dataclass(frozen=True)
class NewEntry:
    kind: str  # "decision" | "error" | "registry" (a registry change through `authn serve`)
    serial: str | None
    decision: str | None  # "accept" | "reject" | None for errors
    payload: dict[str, Any]



@dataclass(frozen=True)
class Entry:
    seq: int
    created_at: datetime
    kind: str
    serial: str | None
    decision: str | None
    payload: dict[str, Any]
    prev_hash: str
    entry_hash: str
    leaf_hash: str | None = None



def _entry(row: Sequence[Any]) -> Entry:
    seq, created, kind, serial, decision, payload, prev, digest, leaf, _ = row
    when = Database.from_db_time(created)
    if when is None:  # NOT NULL in the schema: only a damaged table has none
        raise SystemFault(f"audit entry {seq} has no created_at; run `authn audit verify`")
    return Entry(int(seq), when, kind, serial, decision, json.loads(payload), prev,
                 digest, leaf)



def db_label(db: Database) -> str:
    """Which database an STH line vouches for: its URL, password removed, SQLite path absolute."""
    if db.dialect == "sqlite":
        rest = db.url.split(":///", 1)[1].split("?", 1)[0]
        return "sqlite:///" + str(Path(rest).expanduser().resolve())
    parts = urlsplit(db.url)
    host = parts.hostname or ""
    netloc = (f"{parts.username}@" if parts.username else "") + host + (f":{parts.port}" if parts.port else "")
    return urlunsplit(("postgresql", netloc, parts.path, "", ""))



def lock(db: Database) -> None:
    """Inside a write transaction: serialise against other writers (PostgreSQL's advisory
    lock; SQLite's BEGIN IMMEDIATE already does)."""
    if db.dialect == "postgresql":
        db.execute("SELECT pg_advisory_xact_lock(:k)", {"k": _PG_AUDIT_LOCK})



def batch_entries(db: Database, key: str) -> list[Entry] | None:
    """The entries the committed append with this idempotency key wrote (None: no such append);
    `append` asks inside its transaction, a retried caller may ask first to skip the work."""
    rows = db.fetch("SELECT first_seq, n FROM audit_batches WHERE key = :k", {"k": key})
    if not rows:
        return None
    first, n = int(rows[0][0]), int(rows[0][1])
    return [_entry(r) for r in db.fetch(f"SELECT {COLUMNS} FROM audit_log WHERE seq >= :a AND seq < :b "
                                        "ORDER BY seq", {"a": first, "b": first + n})]



def list_entries(db: Database, *, since: datetime | None = None, decision: str | None = None,
                 serial: str | None = None, kind: str | None = None, limit: int | None = None) -> list[Entry]:
    """Entries in seq order, filtered. `since` compares instants (each stored time read as the
    instant it names, whatever its stored form), so it is applied here, not as text in SQL."""
    where: list[str] = []
    params: dict[str, str | int] = {}
    for name, value in (("decision", decision), ("serial", serial), ("kind", kind)):
        if value is not None:
            where.append(f"{name} = :{name}")
            params[name] = value
    sql = f"SELECT {COLUMNS} FROM audit_log" + (" WHERE " + " AND ".join(where) if where else "") + " ORDER BY seq"
    if since is None:
        if limit is not None:
            sql += " LIMIT :limit"
            params["limit"] = int(limit)
        return [_entry(r) for r in db.fetch(sql, params)]
    out: list[Entry] = []
    for row in db.fetch(sql, params):
        entry = _entry(row)
        if entry.created_at >= since:
            out.append(entry)
            if limit is not None and len(out) >= limit:
                break
    return out


def get_entry(db: Database, seq: int) -> Entry | None:
    rows = db.fetch(f"SELECT {COLUMNS} FROM audit_log WHERE seq = :seq", {"seq": seq})
    return _entry(rows[0]) if rows else None



def get_policy(db: Database, sha256: str) -> str | None:
    rows = db.fetch("SELECT text FROM audit_policies WHERE sha256 = :s", {"s": sha256})
    return str(rows[0][0]) if rows else None
