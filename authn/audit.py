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

from sqlalchemy import select, text
from sqlalchemy.orm import Session

from authn.errors import AuthnError
from registry.models import AuditLog

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

    @classmethod
    def of(cls, row: AuditLog) -> "Entry":
        return cls(row.seq, row.created_at, row.kind, row.serial, row.decision, json.loads(row.payload),
                   row.prev_hash, row.entry_hash)


def _lock_head(session: Session) -> tuple[int, str]:
    """Serialise appenders (SQLite: BEGIN IMMEDIATE already holds the write lock)."""
    if session.get_bind().dialect.name == "postgresql":
        session.execute(text("SELECT pg_advisory_xact_lock(:k)"), {"k": _PG_AUDIT_LOCK})
    head = session.execute(select(AuditLog.seq, AuditLog.entry_hash).order_by(AuditLog.seq.desc())
                           .limit(1)).first()
    return (0, GENESIS) if head is None else (int(head[0]), str(head[1]))


def append(session: Session, entries: Sequence[NewEntry]) -> list[Entry]:
    """Append entries in the caller's transaction (one per check, or one per batch)."""
    seq, prev = _lock_head(session)
    out: list[Entry] = []
    for e in entries:
        if e.kind not in ("decision", "error"):
            raise AuthnError(f"audit entry kind must be 'decision' or 'error', got {e.kind!r}")
        seq += 1
        now = datetime.now(timezone.utc)
        payload = canonical_json(e.payload)
        digest = compute_hash(seq, now, e.kind, e.serial, e.decision, payload, prev)
        session.add(AuditLog(seq=seq, created_at=now, kind=e.kind, serial=e.serial, decision=e.decision,
                             payload=payload, prev_hash=prev, entry_hash=digest))
        out.append(Entry(seq, now, e.kind, e.serial, e.decision, e.payload, prev, digest))
        prev = digest
    session.flush()
    return out


def list_entries(session: Session, *, since: datetime | None = None, decision: str | None = None,
                 serial: str | None = None, kind: str | None = None, limit: int | None = None) -> list[Entry]:
    q = select(AuditLog).order_by(AuditLog.seq)
    if since is not None:
        q = q.where(AuditLog.created_at >= since)
    if decision is not None:
        q = q.where(AuditLog.decision == decision)
    if serial is not None:
        q = q.where(AuditLog.serial == serial)
    if kind is not None:
        q = q.where(AuditLog.kind == kind)
    if limit is not None:
        q = q.limit(limit)
    return [Entry.of(r) for r in session.scalars(q)]


def get_entry(session: Session, seq: int) -> Entry | None:
    row = session.scalars(select(AuditLog).where(AuditLog.seq == seq)).first()
    return None if row is None else Entry.of(row)


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


def _rows(session: Session) -> Iterator[AuditLog]:
    yield from session.scalars(select(AuditLog).order_by(AuditLog.seq, AuditLog.id).execution_options(yield_per=1000))


def verify(session: Session, against: Checkpoint | None = None) -> VerifyReport:
    """Recompute the whole chain; with a checkpoint, also detect truncation and rewrites."""
    prev, size = GENESIS, 0
    checkpoint_hash: str | None = None
    for row in _rows(session):
        expected_seq = size + 1
        if row.seq != expected_seq:
            what = "missing (deleted?)" if row.seq > expected_seq else "duplicated"
            return VerifyReport(False, size, prev, expected_seq, f"entry {expected_seq} is {what}")
        if row.prev_hash != prev:
            return VerifyReport(False, size, prev, row.seq,
                                f"entry {row.seq} does not link to entry {row.seq - 1} (reordered or rewritten)")
        digest = compute_hash(row.seq, row.created_at, row.kind, row.serial, row.decision, row.payload,
                              row.prev_hash)
        if digest != row.entry_hash:
            return VerifyReport(False, size, prev, row.seq, f"entry {row.seq} was modified (hash mismatch)")
        prev, size = digest, row.seq
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


def checkpoint(session: Session) -> Checkpoint:
    """Head hash and size of a verified log (refuses to checkpoint a broken chain)."""
    report = verify(session)
    if not report.ok:
        raise AuthnError(f"audit log does not verify: {report.problem}")
    return Checkpoint(report.size, report.head)
