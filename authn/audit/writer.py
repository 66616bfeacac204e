"""The audit writer: append entries in one transaction, after proving the stored log
extends every head it trusts, and sign the new head.

Every append signs a C2SP checkpoint of the whole log, stores it, and after commit writes
the latest-head file. Every K entries or T seconds (checked at append time) the head is
periodic: it keeps the tree's right edge before its last entry, goes into the STH log
and to the witness with a consistency proof.
    AUTHN_AUDIT_CHECKPOINT_EVERY   K, entries (default 64)
    AUTHN_AUDIT_CHECKPOINT_SECONDS T, seconds (default 300)

Extension before every append: the writer trusts the newest head of each place (the
database, the latest-head file, the STH log, the witness when a periodic head is due),
checks each one's signature and origin, and proves, by root, that the stored log extends
every one of them. It starts from the newest periodic head's right edge, which must fold
(with the entry at its size, re-hashed) to that head's signed root, then re-hashes the
stored leaf bytes of every entry since, each row's columns checked against its bytes:
O(K + log n) per append. Rewrites before the anchor that keep the chain consistent
change the anchor entry or the entries after it, and are refused; an edit before the
anchor that breaks the chain locally is found by `verify` (or by every append with
AUTHN_AUDIT_APPEND_CHECK=full, which starts from the first entry: O(n)).

Policies: `append(..., policy_text=...)` stores the Cedar text once per SHA-256 in
`audit_policies` in the same transaction, so `replay` can re-decide an entry later.
"""

from __future__ import annotations

import hashlib
import time
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import authn.audit.merkle as merkle
from authn.audit.edge import edge_json, signed_edge
from authn.audit import leaf as leaf_bytes
from authn.audit._internal.headrows import HEAD_COLUMNS, Signed, check_head, head_of, store_head
from authn.audit._internal.rows import COLUMNS, ColumnsAltered, MalformedRow, stored_leaf
from authn.audit.entries import GENESIS, Entry, NewEntry, batch_entries, lock
from authn.audit.heads import HeadPlaces, KnownHead, log_origin, writer_key
from authn.audit.logkey import LogKey
from authn.audit.tree_head import SignedTreeHead, canonical_json
from core.errors import AuthnError, SystemFault
from core.settings import current
from registry.dbapi import Database


def append(db: Database, entries: Sequence[NewEntry], *, policy_text: str | None = None,
           log_key: str | Path | None = None, sth_log: str | Path | None = None,
           idempotency_key: str | None = None, witness: str | None = None) -> list[Entry]:
    """Append entries in one transaction (one per check, or one per batch), serialised
    against other writers: SQLite's BEGIN IMMEDIATE, PostgreSQL's advisory lock.

    With `policy_text`, its text is recorded (once per SHA-256) and every entry's payload
    carries its `policy_sha256` (added to entries without one; a different one is refused).
    Before signing, proves that the log extends every head it trusts (see the module
    docstring); signs the new head, and every K entries / T seconds publishes it.

    With `idempotency_key`, the transaction also records the key in `audit_batches`; if a
    transaction with that key already committed, nothing is written and its entries are
    returned instead (a retried append is a no-op: exactly once)."""
    policy_sha = hashlib.sha256(policy_text.encode()).hexdigest() if policy_text is not None else None
    prepared: list[tuple[NewEntry, dict[str, Any], str]] = []
    for e in entries:
        if e.kind not in ("decision", "error", "registry"):
            raise AuthnError(f"audit entry kind must be 'decision', 'error' or 'registry', got {e.kind!r}")
        payload = e.payload
        if policy_sha is not None:
            given = payload.get("policy_sha256")
            if given is None:
                payload = {**payload, "policy_sha256": policy_sha}
            elif given != policy_sha:
                raise AuthnError(f"audit entry policy_sha256 {given} is not the SHA-256 of policy_text")
        prepared.append((e, payload, canonical_json(payload)))
    places = HeadPlaces.of(db, sth_log=sth_log, log_key=log_key, witness=witness)
    settings = current()
    every, seconds = settings.audit_checkpoint_every, settings.audit_checkpoint_seconds
    mode = settings.audit_append_check
    out: list[Entry] = []
    signed: Signed | None = None
    with db.write():
        lock(db)
        if idempotency_key is not None:
            done = batch_entries(db, idempotency_key)
            if done is not None:
                return done
        head = db.fetch("SELECT seq, entry_hash FROM audit_log ORDER BY seq DESC LIMIT 1")
        seq, prev = (0, GENESIS) if not head else (int(head[0][0]), str(head[0][1]))
        if policy_sha is not None:  # once per distinct text: later inserts of it do nothing
            db.execute("INSERT INTO audit_policies (sha256, text, first_seen) VALUES (:s, :t, :f) "
                       "ON CONFLICT (sha256) DO NOTHING",
                       {"s": policy_sha, "t": policy_text, "f": db.to_db_time(datetime.now(timezone.utc))})
        for e, payload, text in prepared:
            seq += 1
            entry = insert_entry(db, seq, prev, e, payload, text)
            out.append(entry)
            prev = entry.entry_hash
        if idempotency_key is not None:
            db.execute("INSERT INTO audit_batches (key, first_seq, n, created_at) VALUES (:k, :f, :n, :c)",
                       {"k": idempotency_key, "f": seq - len(out) + 1, "n": len(out),
                        "c": db.to_db_time(datetime.now(timezone.utc))})
        if out:
            signed = _sign_head(db, places, seq - len(out), seq, every, seconds, mode)
    if signed is not None:
        places.publish(signed)
    return out



def insert_entry(db: Database, seq: int, prev: str, e: NewEntry, payload: dict[str, Any], text: str) -> Entry:
    """Inside an append's transaction: insert entry `seq` (payload as canonical `text`) after
    the entry whose hash is `prev`, stamped now: its leaf bytes (authn.audit.leaf, version 1)
    stored with it, its hashes those of the stored bytes."""
    now = datetime.now(timezone.utc)
    body = leaf_bytes.encode(seq, leaf_bytes.time_text(now), e.kind, e.serial, e.decision, text, prev)
    digest = hashlib.sha256(body).hexdigest()
    leaf = merkle.leaf_hash(body).hex()
    db.execute(f"INSERT INTO audit_log ({COLUMNS}) VALUES (:seq, :created_at, :kind, :serial, "
               ":decision, :payload, :prev_hash, :entry_hash, :leaf_hash, :leaf_bytes)",
               {"seq": seq, "created_at": db.to_db_time(now), "kind": e.kind, "serial": e.serial,
                "decision": e.decision, "payload": text, "prev_hash": prev, "entry_hash": digest, "leaf_hash": leaf,
                "leaf_bytes": body})
    return Entry(seq, now, e.kind, e.serial, e.decision, payload, prev, digest, leaf)


@dataclass(frozen=True)
class _Anchor:
    """Where the writer's proof starts: a signed periodic head whose stored right edge folds
    to its root (so the edge, and the entry at its size, are the ones that were signed), or
    the empty tree; and the newest periodic head, from which the next one is due."""

    size: int
    frontier: merkle.Frontier
    chain: str  # entry_hash of entry `size` (GENESIS at 0)
    periodic_size: int
    periodic_ms: int
    periodic: SignedTreeHead | None = None



def _body(row: Sequence[Any]) -> bytes:
    """A stored row's leaf bytes, its columns agreeing with them; a row the writer never wrote
    is a fault, not a crash."""
    try:
        return stored_leaf(row)
    except MalformedRow as exc:
        what = "was modified" if isinstance(exc, ColumnsAltered) else "is malformed"
        raise SystemFault(f"audit log entry {row[0]} {what} ({exc}); run `authn audit verify`") from None


def _anchor(db: Database, key: LogKey, origin: str, mode: str, size_before: int) -> _Anchor:
    """The newest periodic head, checked against its signature, and its right edge against the
    edge's own signature (authn.audit.edge) and the head's root, with the entry at its size
    re-hashed (window mode). In full mode, when there is none, or when its edge does not
    check (unsigned, altered, moved), the proof starts from the empty tree: that append
    re-hashes every entry and its head is periodic, so the next one has a signed edge."""
    rows = db.fetch(f"SELECT {HEAD_COLUMNS}, frontier FROM audit_tree_heads WHERE frontier IS NOT NULL "
                    "ORDER BY tree_size DESC, id DESC LIMIT 1")
    if not rows:
        return _Anchor(0, merkle.Frontier(), GENESIS, 0, 0)
    try:
        sth = head_of(rows[0][:6])
    except AuthnError:
        raise SystemFault("audit log: the newest periodic head in the database is malformed; "
                          "run `authn audit verify`") from None
    check_head(KnownHead(sth, "database"), key, origin, size_before)
    b = sth.tree_size
    if mode == "full":  # the periodic head is checked by root on the way, like every trusted head
        return _Anchor(0, merkle.Frontier(), GENESIS, b, sth.timestamp, sth)
    edge = signed_edge(rows[0][6], sth, key.public_key) if b else None
    if edge is None:
        return _Anchor(0, merkle.Frontier(), GENESIS, 0, 0, sth)
    entry = db.fetch(f"SELECT {COLUMNS} FROM audit_log WHERE seq = :s", {"s": b})
    if not entry:
        raise SystemFault(f"audit log truncated: entry {b}, which the signed head of size {b} covers, is missing; "
                          "run `authn audit verify`")
    body = _body(entry[0])
    frontier = merkle.Frontier(b - 1, edge)
    frontier.push(merkle.leaf_hash(body))
    if frontier.root() != sth.root:
        raise SystemFault(f"audit log entries 1..{b} differ from the signed head of size {b} (rewritten, deleted "
                          "or reordered); run `authn audit verify`")
    return _Anchor(b, frontier, hashlib.sha256(body).hexdigest(), b, sth.timestamp, sth)


def _vouched(heads: Sequence[KnownHead], fresh: bool, size_before: int) -> None:
    """Refuse to sign over entries no trusted head vouches for: the largest trusted head must
    be of exactly the entries before this append. Only a new log (no entries, no origin)
    starts without one; anything else is history whose heads were deleted or never made,
    which only `authn audit recover` may sign, as it stands and on an operator's word."""
    largest = max((h.sth.tree_size for h in heads), default=None)
    if fresh or largest == size_before:
        return
    what = (f"holds {size_before} entries but no signed head vouches for them" if largest is None
            else f"entries {largest + 1}..{size_before} carry no signed head")
    raise SystemFault(f"audit log {what} (heads deleted, or written outside authn); run `authn audit verify`, "
                      "then `authn audit recover` to sign the log as it stands")


def _sign_head(db: Database, places: "HeadPlaces", size_before: int, size: int, every: int, seconds: float,
               mode: str) -> Signed:
    """Inside append's transaction: prove the log extends every head it trusts, then sign
    the head of all `size` entries (and say whether it is also periodic).

    Trusted: the newest head in the database, the newest periodic one, the latest-head
    file, the newest line of the STH log and, when a periodic head is due, the witness's
    newest. Each must carry this key's signature and name this log; none may be larger
    than the log; the newest in the database (else the newest kept outside it) must be the
    head of exactly the entries before this append, unless the log is new; and the tree the
    stored entries make must have, at each trusted head's size, that head's root. The
    entries since the anchor are re-hashed from their leaf bytes, not taken as stored. Anything
    else raises SystemFault: the transaction rolls back, and nothing is appended to a log
    that does not extend what was signed."""
    named = log_origin(db)
    fresh = size_before == 0 and named is None
    heads = places.newest_heads()
    key = writer_key(db, heads, places.log_key, size=size_before)
    origin = named or log_origin(db, create=True)
    assert origin is not None
    for h in heads:
        check_head(h, key, origin, size_before)
    now_ms = int(time.time() * 1000)
    anchor = _anchor(db, key, origin, mode, size_before)
    due = size - anchor.periodic_size >= every or now_ms - anchor.periodic_ms >= seconds * 1000
    if due and places.witness is not None:
        witnessed = places.witness_heads(origin, newest_only=True)
        for h in witnessed:
            check_head(h, key, origin, size_before)
        heads += witnessed
    in_db = [h for h in heads if h.source == "database"]
    _vouched(in_db or heads, fresh, size_before)  # the database's newest, else those kept outside it
    at: dict[int, list[KnownHead]] = {}
    for h in heads + ([KnownHead(anchor.periodic, "database")] if anchor.periodic is not None else []):
        if h.sth.tree_size >= anchor.size:
            at.setdefault(h.sth.tree_size, []).append(h)
    frontier, chain, expected = anchor.frontier, anchor.chain, anchor.size + 1
    before_last = frontier.hashes if frontier.size == size else []

    def check_roots() -> None:
        for h in at.get(frontier.size, ()):
            if frontier.root() != h.sth.root:
                raise SystemFault(f"audit log entries 1..{h.sth.tree_size} differ from the signed head of that size "
                                  f"({h.source}): rewritten, deleted or reordered; run `authn audit verify`")

    check_roots()
    for row in db.fetch(f"SELECT {COLUMNS} FROM audit_log WHERE seq > :a ORDER BY seq", {"a": anchor.size}):
        seq = row[0]
        if seq != expected or row[6] != chain:
            raise SystemFault(f"audit log entry {expected} is missing, moved or does not link to entry "
                              f"{expected - 1}; run `authn audit verify`")
        body = _body(row)
        chain = hashlib.sha256(body).hexdigest()
        leaf = merkle.leaf_hash(body)
        if chain != row[7] or leaf.hex() != row[8]:
            raise SystemFault(f"audit log entry {seq} was modified (hash mismatch); run `authn audit verify`")
        if seq == size:
            before_last = frontier.hashes
        frontier.push(leaf)
        expected += 1
        check_roots()
    if frontier.size != size:
        raise SystemFault("audit log damaged (entries missing); run `authn audit verify`")
    sth = key.sign_tree_head(size, frontier.root(), now_ms, origin)
    store_head(db, sth, edge_json(key, sth, before_last) if due else None)
    return Signed(sth, due)
