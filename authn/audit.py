"""Hash-chained, append-only audit log of decisions.

Entry n commits to entry n-1: entry_hash = SHA-256 of the canonical JSON of
(seq, created_at, kind, serial, decision, payload, prev_hash). The database
refuses UPDATE and DELETE (triggers from the first migration); `verify`
recomputes the chain, and a checkpoint (head hash + size, kept elsewhere)
also catches truncation and wholesale rewrites.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from datetime import datetime, timezone
from typing import Any

from authn.errors import AuthnError
from registry.dbapi import Database

GENESIS = "0" * 64
_PG_AUDIT_LOCK = 0x61756469_746C6F67  # "auditlog"


def canonical_json(obj: Any) -> str:
    """One byte-exact encoding: sorted keys, no spaces, UTF-8, finite numbers only."""
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), ensure_ascii=False, allow_nan=False)


def _iso(when: datetime) -> str:
    return when.astimezone(timezone.utc).isoformat(timespec="microseconds")


def compute_hash(seq: int, created_at: datetime, kind: str, serial: str | None, decision: str | None,
                 payload: str, prev_hash: str) -> str:
    body = canonical_json({"seq": seq, "created_at": _iso(created_at), "kind": kind, "serial": serial,
                           "decision": decision, "payload": payload, "prev_hash": prev_hash})
    return hashlib.sha256(body.encode("utf-8")).hexdigest()


@dataclass(frozen=True)
class NewEntry:
    kind: str  # "decision" | "error"
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

_COLUMNS = "seq, created_at, kind, serial, decision, payload, prev_hash, entry_hash"


def _entry(row: tuple) -> Entry:
    seq, created, kind, serial, decision, payload, prev, digest = row
    return Entry(int(seq), Database.from_db_time(created), kind, serial, decision, json.loads(payload), prev, digest)


def append(db: Database, entries: Sequence[NewEntry]) -> list[Entry]:
    """Append entries in one transaction (one per check, or one per batch), serialised
    against other writers: SQLite's BEGIN IMMEDIATE, PostgreSQL's advisory lock."""
    for e in entries:
        if e.kind not in ("decision", "error"):
            raise AuthnError(f"audit entry kind must be 'decision' or 'error', got {e.kind!r}")
    out: list[Entry] = []
    with db.write():
        if db.dialect == "postgresql":
            db.execute("SELECT pg_advisory_xact_lock(:k)", {"k": _PG_AUDIT_LOCK})
        head = db.fetch("SELECT seq, entry_hash FROM audit_log ORDER BY seq DESC LIMIT 1")
        seq, prev = (0, GENESIS) if not head else (int(head[0][0]), str(head[0][1]))
        for e in entries:
            seq += 1
            now = datetime.now(timezone.utc)
            payload = canonical_json(e.payload)
            digest = compute_hash(seq, now, e.kind, e.serial, e.decision, payload, prev)
            db.execute(f"INSERT INTO audit_log ({_COLUMNS}) VALUES "
                       "(:seq, :created_at, :kind, :serial, :decision, :payload, :prev_hash, :entry_hash)",
                       {"seq": seq, "created_at": db.to_db_time(now), "kind": e.kind, "serial": e.serial,
                        "decision": e.decision, "payload": payload, "prev_hash": prev, "entry_hash": digest})
            out.append(Entry(seq, now, e.kind, e.serial, e.decision, e.payload, prev, digest))
            prev = digest
    return out


def list_entries(db: Database, *, since: datetime | None = None, decision: str | None = None,
                 serial: str | None = None, kind: str | None = None, limit: int | None = None) -> list[Entry]:
    where, params = [], {}
    for name, value in (("decision", decision), ("serial", serial), ("kind", kind)):
        if value is not None:
            where.append(f"{name} = :{name}")
            params[name] = value
    if since is not None:
        where.append("created_at >= :since")
        params["since"] = db.to_db_time(since)
    sql = f"SELECT {_COLUMNS} FROM audit_log" + (" WHERE " + " AND ".join(where) if where else "") + " ORDER BY seq"
    if limit is not None:
        sql += " LIMIT :limit"
        params["limit"] = int(limit)
    return [_entry(r) for r in db.fetch(sql, params)]


def get_entry(db: Database, seq: int) -> Entry | None:
    rows = db.fetch(f"SELECT {_COLUMNS} FROM audit_log WHERE seq = :seq", {"seq": seq})
    return _entry(rows[0]) if rows else None


@dataclass(frozen=True)
class Checkpoint:
    size: int
    head: str

    def to_json(self) -> str:
        return canonical_json({"format": "authn-audit-checkpoint/1", "size": self.size, "head": self.head})

    @classmethod
    def from_json(cls, text_: str) -> "Checkpoint":
        try:
            doc = json.loads(text_)
            if doc.get("format") != "authn-audit-checkpoint/1":
                raise ValueError("format")
            size, head = int(doc["size"]), str(doc["head"])
        except (ValueError, TypeError, KeyError, AttributeError):
            raise AuthnError("checkpoint: not an authn-audit-checkpoint/1 JSON document") from None
        if size < 0 or len(head) != 64:
            raise AuthnError("checkpoint: bad size or head hash")
        return cls(size, head)


@dataclass(frozen=True)
class VerifyReport:
    ok: bool
    size: int
    head: str
    first_bad_seq: int | None = None
    problem: str | None = None


def _rows(db: Database) -> Iterator[tuple]:
    """Raw rows in seq order, a page at a time (the payload is hashed as stored)."""
    last = None
    while True:
        page = db.fetch(f"SELECT {_COLUMNS} FROM audit_log" + ("" if last is None else " WHERE seq > :last")
                        + " ORDER BY seq, id LIMIT 1000", {} if last is None else {"last": last})
        yield from page
        if len(page) < 1000:
            return
        last = page[-1][0]


def verify(db: Database, against: Checkpoint | None = None) -> VerifyReport:
    """Recompute the whole chain; with a checkpoint, also detect truncation and rewrites."""
    prev, size = GENESIS, 0
    checkpoint_hash: str | None = None
    for seq, created, kind, serial, decision, payload, prev_hash, entry_hash in _rows(db):
        expected_seq = size + 1
        if seq != expected_seq:
            what = "missing (deleted?)" if seq > expected_seq else "duplicated"
            return VerifyReport(False, size, prev, expected_seq, f"entry {expected_seq} is {what}")
        if prev_hash != prev:
            return VerifyReport(False, size, prev, seq,
                                f"entry {seq} does not link to entry {seq - 1} (reordered or rewritten)")
        digest = compute_hash(seq, Database.from_db_time(created), kind, serial, decision, payload, prev_hash)
        if digest != entry_hash:
            return VerifyReport(False, size, prev, seq, f"entry {seq} was modified (hash mismatch)")
        prev, size = digest, seq
        if against is not None and size == against.size:
            checkpoint_hash = digest
    if against is not None:
        if size < against.size:
            return VerifyReport(False, size, prev, size + 1,
                                f"log truncated: {size} entries, checkpoint has {against.size}")
        if against.size > 0 and checkpoint_hash != against.head:
            return VerifyReport(False, size, prev, against.size,
                                f"entry {against.size} differs from the checkpoint (history rewritten)")
    return VerifyReport(True, size, prev)


def checkpoint(db: Database) -> Checkpoint:
    """Head hash and size of a verified log (refuses to checkpoint a broken chain)."""
    report = verify(db)
    if not report.ok:
        raise AuthnError(f"audit log does not verify: {report.problem}")
    return Checkpoint(report.size, report.head)
