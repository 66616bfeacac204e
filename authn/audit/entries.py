"""Audit entries: their canonical bytes (the hash chain's and the Merkle tree's input),
the rows that hold them, and reading them back.

Leaf bytes: the canonical JSON of (seq, created_at, kind, serial, decision, payload text,
prev_hash) -- the very bytes whose SHA-256 is entry_hash. The leaf hash is
SHA-256(0x00 || those bytes) (domain-separated from entry_hash), so one serialisation
serves both; a proof carries the entry itself, not a hash of a hash; and the leaf also
commits to the chain link. Each row stores its leaf hash so proofs and checkpoints never
re-serialise the log; the writer and verify recompute and compare them.
"""

from __future__ import annotations

import hashlib
import json
import re
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit, urlunsplit

from registry.dbapi import Database

GENESIS = "0" * 64

_PG_AUDIT_LOCK = 0x61756469_746C6F67  # "auditlog"

PAGE = 5000

_ENC = json.JSONEncoder(sort_keys=True, separators=(",", ":"), ensure_ascii=False, allow_nan=False)



def _iso(when: datetime) -> str:
    return when.astimezone(timezone.utc).isoformat(timespec="microseconds")



class MalformedRow(ValueError):
    """A stored audit row that the writer could not have written: a column of the wrong type,
    or a time not in the one stored form (verify reports it at that entry)."""


#: created_at as the writer stores it in SQLite (Database.SQLITE_TIME, UTC): the only text accepted
_SQLITE_CANONICAL = re.compile(r"\d{4}-\d{2}-\d{2} \d{2}:\d{2}:\d{2}\.\d{6}")


def _iso_db(value: Any) -> str:
    """created_at as hashed, from the stored value: SQLite's text exactly as the writer stores
    it, or PostgreSQL's timestamptz (an instant). Any other representation, the same instant
    in another UTC offset included, raises MalformedRow: one instant has one stored form."""
    if isinstance(value, str) and _SQLITE_CANONICAL.fullmatch(value):  # one text per instant: any other
        return f"{value[:10]}T{value[11:]}+00:00"                         # text changes the hashed bytes
    if isinstance(value, datetime) and value.tzinfo is not None and value.utcoffset() is not None:
        return _iso(value)
    shown = value if isinstance(value, str) else type(value).__name__
    raise MalformedRow(f"created_at {shown!r} is not a UTC time in the form the writer stores")


def entry_bytes(seq: int, created_iso: str, kind: str, serial: str | None, decision: str | None,
                payload: str, prev_hash: str) -> bytes:
    """The canonical entry: SHA-256 of it is entry_hash; it is also the Merkle leaf."""
    return _ENC.encode({"seq": seq, "created_at": created_iso, "kind": kind, "serial": serial,
                        "decision": decision, "payload": payload, "prev_hash": prev_hash}).encode("utf-8")



def compute_hash(seq: int, created_at: datetime, kind: str, serial: str | None, decision: str | None,
                 payload: str, prev_hash: str) -> str:
    return hashlib.sha256(entry_bytes(seq, _iso(created_at), kind, serial, decision, payload, prev_hash)).hexdigest()



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



_COLUMNS = "seq, created_at, kind, serial, decision, payload, prev_hash, entry_hash, leaf_hash"



def _entry(row: tuple) -> Entry:
    seq, created, kind, serial, decision, payload, prev, digest, leaf = row
    return Entry(int(seq), Database.from_db_time(created), kind, serial, decision, json.loads(payload), prev,
                 digest, leaf)



_TEXT_COLUMNS = ("kind", "serial", "decision", "payload", "prev_hash", "entry_hash", "leaf_hash")
_OPTIONAL = ("serial", "decision", "leaf_hash")


def row_body(row: Sequence[Any]) -> bytes:
    """The canonical bytes of a stored row (a row of _COLUMNS), re-serialised from its content;
    MalformedRow when a column holds what the writer never stores (a BLOB, a number, an
    offset time)."""
    seq, created, kind, serial, decision, payload, prev_hash, entry_hash, leaf = row
    if type(seq) is not int:
        raise MalformedRow("seq is not an integer")
    for name, value in zip(_TEXT_COLUMNS, (kind, serial, decision, payload, prev_hash, entry_hash, leaf)):
        if value.__class__ is not str and not (value is None and name in _OPTIONAL):
            raise MalformedRow(f"{name} is {type(value).__name__}, not text")
    return entry_bytes(seq, _iso_db(created), kind, serial, decision, payload, prev_hash)


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
    return [_entry(r) for r in db.fetch(f"SELECT {_COLUMNS} FROM audit_log WHERE seq >= :a AND seq < :b "
                                        "ORDER BY seq", {"a": first, "b": first + n})]



def list_entries(db: Database, *, since: datetime | None = None, decision: str | None = None,
                 serial: str | None = None, kind: str | None = None, limit: int | None = None) -> list[Entry]:
    """Entries in seq order, filtered. `since` compares instants (each stored time read as the
    instant it names, whatever its stored form), so it is applied here, not as text in SQL."""
    where, params = [], {}
    for name, value in (("decision", decision), ("serial", serial), ("kind", kind)):
        if value is not None:
            where.append(f"{name} = :{name}")
            params[name] = value
    sql = f"SELECT {_COLUMNS} FROM audit_log" + (" WHERE " + " AND ".join(where) if where else "") + " ORDER BY seq"
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
    rows = db.fetch(f"SELECT {_COLUMNS} FROM audit_log WHERE seq = :seq", {"seq": seq})
    return _entry(rows[0]) if rows else None



def get_policy(db: Database, sha256: str) -> str | None:
    rows = db.fetch("SELECT text FROM audit_policies WHERE sha256 = :s", {"s": sha256})
    return str(rows[0][0]) if rows else None



def _rows(db: Database) -> Iterator[tuple]:
    """Raw rows in seq order, a page at a time (keyset pagination; payload hashed as stored)."""
    last = None
    while True:
        page = db.fetch(f"SELECT {_COLUMNS} FROM audit_log" + ("" if last is None else " WHERE seq > :last")
                        + f" ORDER BY seq, id LIMIT {PAGE}", {} if last is None else {"last": last})
        yield from page
        if len(page) < PAGE:
            return
        last = page[-1][0]
