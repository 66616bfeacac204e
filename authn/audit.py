"""Tamper-evident audit log of decisions: a hash chain whose entries are the leaves of an
RFC 9162 Merkle tree, with signed tree heads (STHs) kept outside the database.

Why both: the chain (entry_hash = SHA-256(canonical entry), each entry naming the previous
one's hash) finds the first bad row by itself; the tree gives what the chain cannot --
short inclusion proofs a third party checks with only the log's public key, and
consistency proofs that today's log extends the one an old STH signed. Neither uses a
secret, so only signatures protect against someone who can write the database: an STH
signed by the log key (authn.logkey, a file the database never holds) and stored
elsewhere fixes the first tree_size entries.

Leaf bytes: the canonical JSON of (seq, created_at, kind, serial, decision, payload text,
prev_hash) -- the very bytes whose SHA-256 is entry_hash. The leaf hash is
SHA-256(0x00 || those bytes) (domain-separated from entry_hash), so one serialisation
serves both; a proof carries the entry itself, not a hash of a hash; and the leaf also
commits to the chain link. Each row stores its leaf hash (leaf_hash) so proofs and
checkpoints never re-serialise the log; verify recomputes and compares them.

Heads: every append signs a C2SP checkpoint of the whole log (authn.logkey), whose origin
line names this log (audit_log_meta), stores it in `audit_tree_heads` and, after commit,
in the latest-head file beside the STH log. Every K entries or T seconds (checked at
append time) the head is periodic: it also keeps the tree's right edge before its last
entry, goes as one line into the STH log (AUTHN_AUDIT_STH_LOG) and to the witness
(--witness / AUTHN_AUDIT_WITNESS, authn.witness) with a consistency proof.
    AUTHN_AUDIT_CHECKPOINT_EVERY   K, entries (default 64)
    AUTHN_AUDIT_CHECKPOINT_SECONDS T, seconds (default 300)

Extension before every append: the writer trusts the newest head of each place (the
database, the latest-head file, the STH log, the witness when a periodic head is due),
checks each one's signature and origin, and proves, by root, that the stored log extends
every one of them. It starts from the newest periodic head's right edge, which must fold
(with the entry at its size, re-hashed) to that head's signed root, then re-serialises and
re-hashes every entry since: O(K + log n) per append. Rewrites before the anchor that keep
the chain consistent change the anchor entry or the entries after it, and are refused;
an edit before the anchor that breaks the chain locally is found by `verify` (or by every
append with AUTHN_AUDIT_APPEND_CHECK=full, which starts from the first entry: O(n)).

Policies: `append(..., policy_text=...)` stores the Cedar text once per SHA-256 in
`audit_policies` in the same transaction, so `replay` can re-decide an entry later.
"""

from __future__ import annotations

import hashlib
import json
import os
import secrets
import sys
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit, urlunsplit

from authn import merkle
from authn.errors import AuthnError, SystemFault, one_line
from authn.logkey import CHECKPOINT_FORMAT, LogKey, SignedTreeHead, append_sth_log, canonical_json, \
    create_key_file, key_path, latest_head_path, load_retired_keys, newest_in_sth_log, retired_keys_path, read_latest_head, read_sth_log, sth_log_path, write_latest_head
from authn.witness import Conflict, HttpWitness, WitnessStore, open_witness
from registry.dbapi import Database

GENESIS = "0" * 64
_PG_AUDIT_LOCK = 0x61756469_746C6F67  # "auditlog"
ENV_EVERY = "AUTHN_AUDIT_CHECKPOINT_EVERY"
ENV_SECONDS = "AUTHN_AUDIT_CHECKPOINT_SECONDS"
ENV_CHECK = "AUTHN_AUDIT_APPEND_CHECK"
ENV_ORIGIN = "AUTHN_AUDIT_ORIGIN"
DEFAULT_EVERY, DEFAULT_SECONDS = 64, 300.0
PROOF_FORMAT = "authn-inclusion-proof/1"
PAGE = 5000

_ENC = json.JSONEncoder(sort_keys=True, separators=(",", ":"), ensure_ascii=False, allow_nan=False)
_KEYS: dict[Path, tuple[tuple[int, int] | None, LogKey]] = {}


def _iso(when: datetime) -> str:
    return when.astimezone(timezone.utc).isoformat(timespec="microseconds")


def _iso_db(value: Any) -> str:
    """created_at as hashed, from the stored value (SQLite text or a PostgreSQL datetime)."""
    if isinstance(value, str) and len(value) == 26 and value[10] == " ":  # Database.SQLITE_TIME, UTC
        return f"{value[:10]}T{value[11:]}+00:00"
    return _iso(Database.from_db_time(value))


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


# --- configuration -----------------------------------------------------------------------

def _env_number(name: str, default: float, kind: type) -> Any:
    raw = os.environ.get(name)
    if raw is None or raw == "":
        return kind(default)
    try:
        value = kind(raw)
    except ValueError:
        raise AuthnError(f"${name}: not a number: {raw!r}") from None
    if value <= 0:
        raise AuthnError(f"${name}: must be positive, got {raw!r}")
    return value


def _append_check() -> str:
    mode = os.environ.get(ENV_CHECK) or "window"
    if mode not in ("window", "full"):
        raise AuthnError(f"${ENV_CHECK}: 'window' or 'full', got {mode!r}")
    return mode


def _log_key(path: str | Path | None) -> LogKey:
    """The key at `path`, loaded once per file version (a replaced file is loaded again)."""
    p = key_path(path)
    try:
        st = p.stat()
        version = (st.st_ino, st.st_mtime_ns)
    except OSError:
        version = None
    cached = _KEYS.get(p)
    if cached is None or cached[0] != version or version is None:
        _KEYS[p] = (version, LogKey.load(p))
    return _KEYS[p][1]


def writer_key(db: Database, heads: Sequence["KnownHead"], log_key: str | Path | None = None) -> LogKey:
    """The log key; created only for a log that has no signed head anywhere yet. A log with
    heads and no key is a fault: a new key would let whoever made it re-sign history."""
    p = key_path(log_key)
    if not p.exists():
        if heads or db.fetch("SELECT tree_size FROM audit_tree_heads LIMIT 1"):
            raise SystemFault(f"audit log key {p} is missing but the log has signed heads: restore the key file "
                              "(a new one is never made for a signed log; `authn audit rotate-key` changes it)")
        create_key_file(p)
    return _log_key(p)


def db_label(db: Database) -> str:
    """Which database an STH line vouches for: its URL, password removed, SQLite path absolute."""
    if db.dialect == "sqlite":
        rest = db.url.split(":///", 1)[1].split("?", 1)[0]
        return "sqlite:///" + str(Path(rest).expanduser().resolve())
    parts = urlsplit(db.url)
    host = parts.hostname or ""
    netloc = (f"{parts.username}@" if parts.username else "") + host + (f":{parts.port}" if parts.port else "")
    return urlunsplit(("postgresql", netloc, parts.path, "", ""))


def log_origin(db: Database, *, create: bool = False) -> str | None:
    """The name this log's checkpoints carry (audit_log_meta), made once inside the first
    append's transaction: $AUTHN_AUDIT_ORIGIN, else authn.invalid/audit/<random>."""
    rows = db.fetch("SELECT value FROM audit_log_meta WHERE name = 'origin'")
    if rows:
        return str(rows[0][0])
    if not create:
        return None
    origin = os.environ.get(ENV_ORIGIN) or f"authn.invalid/audit/{secrets.token_hex(8)}"
    try:
        SignedTreeHead(0, 0, GENESIS, "", "", origin).note_body()
        from authn.logkey import _check_origin

        _check_origin(origin)
    except ValueError:
        raise AuthnError(f"${ENV_ORIGIN}: not a checkpoint origin (no spaces, '+' or control characters)") from None
    db.execute("INSERT INTO audit_log_meta (name, value) VALUES ('origin', :v)", {"v": origin})
    return origin


# --- append ------------------------------------------------------------------------------

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
    every = _env_number(ENV_EVERY, DEFAULT_EVERY, int)
    seconds = _env_number(ENV_SECONDS, DEFAULT_SECONDS, float)
    mode = _append_check()
    out: list[Entry] = []
    signed: _Signed | None = None
    with db.write():
        if db.dialect == "postgresql":
            db.execute("SELECT pg_advisory_xact_lock(:k)", {"k": _PG_AUDIT_LOCK})
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
            now = datetime.now(timezone.utc)
            body = entry_bytes(seq, _iso(now), e.kind, e.serial, e.decision, text, prev)
            digest = hashlib.sha256(body).hexdigest()
            leaf = merkle.leaf_hash(body).hex()
            db.execute(f"INSERT INTO audit_log ({_COLUMNS}) VALUES (:seq, :created_at, :kind, :serial, "
                       ":decision, :payload, :prev_hash, :entry_hash, :leaf_hash)",
                       {"seq": seq, "created_at": db.to_db_time(now), "kind": e.kind, "serial": e.serial,
                        "decision": e.decision, "payload": text, "prev_hash": prev, "entry_hash": digest,
                        "leaf_hash": leaf})
            out.append(Entry(seq, now, e.kind, e.serial, e.decision, payload, prev, digest, leaf))
            prev = digest
        if idempotency_key is not None:
            db.execute("INSERT INTO audit_batches (key, first_seq, n, created_at) VALUES (:k, :f, :n, :c)",
                       {"k": idempotency_key, "f": seq - len(out) + 1, "n": len(out),
                        "c": db.to_db_time(datetime.now(timezone.utc))})
        if out:
            signed = _sign_head(db, places, seq - len(out), seq, every, seconds, mode)
    if signed is not None:
        places.publish(signed)
    return out


def batch_entries(db: Database, key: str) -> list[Entry] | None:
    """The entries the committed append with this idempotency key wrote (None: no such append);
    `append` asks inside its transaction, a retried caller may ask first to skip the work."""
    rows = db.fetch("SELECT first_seq, n FROM audit_batches WHERE key = :k", {"k": key})
    if not rows:
        return None
    first, n = int(rows[0][0]), int(rows[0][1])
    return [_entry(r) for r in db.fetch(f"SELECT {_COLUMNS} FROM audit_log WHERE seq >= :a AND seq < :b "
                                        "ORDER BY seq", {"a": first, "b": first + n})]


_HEAD_COLUMNS = "tree_size, timestamp_ms, root_hash, log_key_id, signature, origin"


def _head_of(row: Sequence[Any]) -> SignedTreeHead:
    """A head from a row of _HEAD_COLUMNS (AuthnError when malformed)."""
    n, ts, root, kid, sig, origin = row
    fmt = "authn-sth/1" if origin is None else CHECKPOINT_FORMAT
    return SignedTreeHead.from_dict({"format": fmt, "tree_size": int(n), "timestamp": int(ts), "root_hash": root,
                                     "log_key_id": str(kid).strip(), "signature": sig, "origin": origin})


@dataclass(frozen=True)
class _Signed:
    sth: SignedTreeHead
    due: bool  # periodic: also to the STH log and the witness
    frontier: merkle.Frontier  # at sth.tree_size


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


def _anchor(db: Database, key: LogKey, origin: str, mode: str, size_before: int) -> _Anchor:
    """The newest periodic head, checked against its signature and root (window mode); in
    full mode, or when there is none, the proof starts from the empty tree."""
    rows = db.fetch(f"SELECT {_HEAD_COLUMNS}, frontier FROM audit_tree_heads WHERE frontier IS NOT NULL "
                    "ORDER BY tree_size DESC, id DESC LIMIT 1")
    if not rows:
        return _Anchor(0, merkle.Frontier(), GENESIS, 0, 0)
    try:
        sth = _head_of(rows[0][:6])
    except AuthnError:
        raise SystemFault("audit log: the newest periodic head in the database is malformed; "
                          "run `authn audit verify`") from None
    _check_head(KnownHead(sth, "database"), key, origin, size_before)
    b = sth.tree_size
    if mode == "full":  # the periodic head is checked by root on the way, like every trusted head
        return _Anchor(0, merkle.Frontier(), GENESIS, b, sth.timestamp, sth)
    entry = db.fetch(f"SELECT {_COLUMNS} FROM audit_log WHERE seq = :s", {"s": b}) if b else []
    try:
        edge = json.loads(rows[0][6])
        if isinstance(edge, dict):  # the edge before the last entry: the entry itself is checked too
            if not entry:
                raise ValueError
            body = _row_body(entry[0])
            frontier = merkle.Frontier(b - 1, [bytes.fromhex(h) for h in edge["before_last"]])
            frontier.push(merkle.leaf_hash(body))
            chain = hashlib.sha256(body).hexdigest()
        else:  # an edge stored before revision 0005: the entry at its size is taken as stored
            frontier = merkle.Frontier(b, [bytes.fromhex(h) for h in edge])
            chain = str(entry[0][7]) if entry else ""
    except (ValueError, TypeError, KeyError):
        raise SystemFault(f"audit log: the right edge stored with the head of size {b} is damaged; "
                          "run `authn audit verify`") from None
    if frontier.root() != sth.root:
        raise SystemFault(f"audit log entries 1..{b} differ from the signed head of size {b} (rewritten, deleted "
                          "or reordered); run `authn audit verify`")
    return _Anchor(b, frontier, chain, b, sth.timestamp, sth)


def _row_body(row: Sequence[Any]) -> bytes:
    seq, created, kind, serial, decision, payload, prev_hash, _, _ = row
    return entry_bytes(int(seq), _iso_db(created), kind, serial, decision, payload, prev_hash)


def _check_head(h: "KnownHead", key: LogKey, origin: str, size_before: int) -> None:
    """A trusted head must be this key's, name this log, and not be larger than the log."""
    if not key.vouches_for(h.sth):
        raise SystemFault(f"audit log: the signed head of size {h.sth.tree_size} ({h.source}) is not signed by "
                          "this log's key; run `authn audit verify`")
    if h.sth.origin is not None and h.sth.origin != origin:
        raise SystemFault(f"audit log: the signed head of size {h.sth.tree_size} ({h.source}) names the log "
                          f"{h.sth.origin}, not this one ({origin})")
    if h.sth.tree_size > size_before:
        raise SystemFault(f"audit log truncated: {size_before} entries, but the signed head ({h.source}) has "
                          f"{h.sth.tree_size}; run `authn audit verify`")


def _sign_head(db: Database, places: "HeadPlaces", size_before: int, size: int, every: int, seconds: float,
               mode: str) -> _Signed:
    """Inside append's transaction: prove the log extends every head it trusts, then sign
    the head of all `size` entries (and say whether it is also periodic).

    Trusted: the newest head in the database, the newest periodic one, the latest-head
    file, the newest line of the STH log and, when a periodic head is due, the witness's
    newest. Each must carry this key's signature and name this log; none may be larger
    than the log; the newest in the database must be the head of exactly the entries
    before this append; and the tree the stored entries make must have, at each trusted
    head's size, that head's root. The entries since the anchor are re-serialised and
    re-hashed, not taken as stored. Anything else raises SystemFault: the transaction rolls
    back, and nothing is appended to a log that does not extend what was signed."""
    origin = log_origin(db, create=True)
    assert origin is not None
    heads = places.newest_heads(db)
    key = writer_key(db, heads, places.log_key)
    for h in heads:
        _check_head(h, key, origin, size_before)
    now_ms = int(time.time() * 1000)
    anchor = _anchor(db, key, origin, mode, size_before)
    due = size - anchor.periodic_size >= every or now_ms - anchor.periodic_ms >= seconds * 1000
    if due and places.witness is not None:
        witnessed = places.witness_heads(origin, newest_only=True)
        for h in witnessed:
            _check_head(h, key, origin, size_before)
        heads += witnessed
    in_db = [h for h in heads if h.source == "database"]
    if in_db and max(h.sth.tree_size for h in in_db) != size_before:
        raise SystemFault(f"audit log entries {max(h.sth.tree_size for h in in_db) + 1}..{size_before} carry no "
                          "signed head (written outside authn?); run `authn audit verify`")
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
    for row in db.fetch(f"SELECT {_COLUMNS} FROM audit_log WHERE seq > :a ORDER BY seq", {"a": anchor.size}):
        seq = int(row[0])
        if seq != expected or row[6] != chain:
            raise SystemFault(f"audit log entry {expected} is missing, moved or does not link to entry "
                              f"{expected - 1}; run `authn audit verify`")
        body = _row_body(row)
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
    edge = json.dumps({"before_last": [h.hex() for h in before_last]}) if due else None
    _store_head(db, sth, edge)
    return _Signed(sth, due, frontier)


def _store_head(db: Database, sth: SignedTreeHead, edge: str | None) -> SignedTreeHead:
    db.execute("INSERT INTO audit_tree_heads (tree_size, timestamp_ms, root_hash, log_key_id, signature, frontier, "
               "origin) VALUES (:n, :t, :r, :k, :s, :f, :o)",
               {"n": sth.tree_size, "t": sth.timestamp, "r": sth.root_hash, "k": sth.log_key_id,
                "s": sth.signature, "f": edge, "o": sth.origin})
    return sth


# --- reading -----------------------------------------------------------------------------

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


# --- where heads are kept ------------------------------------------------------------------

@dataclass(frozen=True)
class KnownHead:
    sth: SignedTreeHead
    source: str  # "database" | "file PATH" | "witness W" | "--against FILE"


def _newest_of(heads: Sequence[SignedTreeHead]) -> SignedTreeHead | None:
    """The largest head, the last written among equals (a rotation's new-key head)."""
    best = None
    for h in heads:
        if best is None or h.tree_size >= best.tree_size:
            best = h
    return best


@dataclass
class HeadPlaces:
    """Every place a head of this log is kept: the database, the latest-head file, the STH
    log and the witness. The writer and `verify` read their trusted heads from here."""

    db: Database
    label: str
    sth_log: Path
    latest_file: Path
    log_key: Path
    witness: WitnessStore | HttpWitness | None

    @classmethod
    def of(cls, db: Database, *, sth_log: str | Path | None = None, log_key: str | Path | None = None,
           witness: str | None = None) -> "HeadPlaces":
        path = sth_log_path(sth_log, log_key)
        label = db_label(db)
        return cls(db, label, path, latest_head_path(path, label), key_path(log_key), open_witness(witness))

    def _db_heads(self, where: str, params: dict[str, Any] | None = None) -> list[KnownHead]:
        out = []
        for row in self.db.fetch(f"SELECT {_HEAD_COLUMNS} FROM audit_tree_heads {where}", params or {}):
            try:
                out.append(KnownHead(_head_of(row), "database"))
            except AuthnError:
                out.append(KnownHead(SignedTreeHead(int(row[0]), int(row[1]), GENESIS, "", ""),
                                     "database (malformed)"))
        return out

    def newest_heads(self, db: Database) -> list[KnownHead]:
        """What the writer trusts: the newest head in the database, the latest-head file, the
        newest STH log line for this database (the witness is asked separately)."""
        out = self._db_heads("ORDER BY tree_size DESC, id DESC LIMIT 1")
        latest = read_latest_head(self.latest_file)
        if latest is not None:
            out.append(KnownHead(latest, f"file {self.latest_file}"))
        logged = newest_in_sth_log(self.sth_log, self.label)
        if logged is not None:
            out.append(KnownHead(logged, f"file {self.sth_log}"))
        return out

    def all_heads(self) -> list[KnownHead]:
        """What `verify` checks: every periodic head and the newest in the database, every STH
        log line for this database, the latest-head file, and every head the witness holds."""
        out = [KnownHead(sth, f"file {self.sth_log}") for owner, sth in read_sth_log(self.sth_log)
               if owner == self.label]
        latest = read_latest_head(self.latest_file)
        if latest is not None:
            out.append(KnownHead(latest, f"file {self.latest_file}"))
        newest_id = self.db.fetch("SELECT id FROM audit_tree_heads ORDER BY tree_size DESC, id DESC LIMIT 1")
        out += self._db_heads("WHERE frontier IS NOT NULL OR id = :newest ORDER BY id",
                              {"newest": newest_id[0][0] if newest_id else -1})
        origin = log_origin(self.db)
        if self.witness is not None and origin is not None:
            out += self.witness_heads(origin, newest_only=False)
        return out

    def witness_heads(self, origin: str, *, newest_only: bool) -> list[KnownHead]:
        assert self.witness is not None
        held = self.witness.heads(origin)
        if newest_only:
            newest_held = _newest_of(held)
            held = [newest_held] if newest_held is not None else []
        return [KnownHead(h, f"witness {self.witness.name}") for h in held]

    def publish(self, signed: _Signed) -> None:
        """After commit: the latest-head file always; periodic heads to the STH log and the witness."""
        write_latest_head(self.latest_file, signed.sth, self.label)
        if not signed.due:
            return
        append_sth_log(self.sth_log, signed.sth, self.label)
        if self.witness is not None:
            self.witness_add(signed.sth)

    def witness_add(self, sth: SignedTreeHead, *cosigned: SignedTreeHead, keys: Sequence[Any] = ()) -> None:
        """Give the witness `sth` with a consistency proof from the newest head it holds. A
        refusal is a fault (it holds history this log no longer has); an unreachable
        witness is only reported: the next periodic head carries the proof from where it is."""
        assert self.witness is not None and sth.origin is not None
        try:
            held = _newest_of(self.witness.heads(sth.origin))
            old = held.tree_size if held is not None else 0
            proof = consistency_proof(self.db, old, sth.tree_size)
            for head in (sth, *cosigned):
                self.witness.add(head, old, proof, list(keys) or [_log_key(self.log_key).public_key])
        except Conflict as exc:
            raise SystemFault(f"witness {self.witness.name} refused the head of size {sth.tree_size}: {exc}") from None
        except SystemFault as exc:
            print(f"authn: warning: {one_line(str(exc))}; the witness gets the next periodic head", file=sys.stderr)


def consistency_proof(db: Database, old: int, new: int) -> list[bytes]:
    """PROOF(old, new) over the stored leaf hashes: from the right edge stored with a periodic
    head of size `old` (O(new - old + log new)), else one pass over the leaves."""
    if old == 0 or old == new:
        return []
    frontier: merkle.Frontier | None = None
    rows = db.fetch("SELECT frontier FROM audit_tree_heads WHERE tree_size = :n AND frontier IS NOT NULL "
                    "ORDER BY id DESC LIMIT 1", {"n": old})
    try:
        edge = json.loads(rows[0][0]) if rows else None
        if isinstance(edge, dict):
            leaf = db.fetch("SELECT leaf_hash FROM audit_log WHERE seq = :s", {"s": old})
            frontier = merkle.Frontier(old - 1, [bytes.fromhex(h) for h in edge["before_last"]])
            frontier.push(bytes.fromhex(leaf[0][0]))
        elif isinstance(edge, list):
            frontier = merkle.Frontier(old, [bytes.fromhex(h) for h in edge])
    except (ValueError, TypeError, KeyError, IndexError):
        frontier = None
    if frontier is None:
        frontier = merkle.Frontier()
        for (h,) in db.fetch("SELECT leaf_hash FROM audit_log WHERE seq <= :n ORDER BY seq", {"n": old}):
            frontier.push(bytes.fromhex(h))
    leaves = [bytes.fromhex(h) for (h,) in db.fetch("SELECT leaf_hash FROM audit_log WHERE seq > :a AND seq <= :b "
                                                     "ORDER BY seq", {"a": old, "b": new})]
    return merkle.consistency_proof_from(frontier, leaves)


def known_heads(db: Database, *, sth_log: str | Path | None = None, log_key: str | Path | None = None,
                witness: str | None = None) -> list[KnownHead]:
    """Every head of this log kept anywhere (unverified): what `verify` checks the log against."""
    return HeadPlaces.of(db, sth_log=sth_log, log_key=log_key, witness=witness).all_heads()


def newest(heads: Sequence[KnownHead]) -> KnownHead | None:
    return max(heads, key=lambda h: (h.sth.tree_size, h.sth.timestamp, h.source.startswith("file")), default=None)


# --- verify ------------------------------------------------------------------------------

@dataclass(frozen=True)
class VerifyReport:
    ok: bool
    size: int
    head: str  # chain head (entry_hash of the last entry)
    root: str = ""  # Merkle tree head of all entries, hex
    first_bad_seq: int | None = None
    problem: str | None = None
    checked: list[str] = field(default_factory=list)  # the STHs the log was found consistent with
    unsigned: int = 0  # entries after the largest STH checked (protected by the chain only)


def _when(ms: int) -> str:
    return datetime.fromtimestamp(ms / 1000, timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")


def accepted_keys(heads: Sequence[KnownHead], current: Any, retired: Sequence[Any] = ()) -> list[Any]:
    """The current key, and each retired key that signed a head which a key already accepted
    signed too (the rotation head `authn audit rotate-key` signs with both): a retired key
    nobody handed over from is not accepted, whatever file lists it."""
    keys, pending = [current], list(retired)
    grown = True
    while grown and pending:
        grown = False
        for r in list(pending):
            by_r = {h.sth.signed_bytes() for h in heads if h.sth.origin is not None and h.sth.verify_signature(r)}
            if any(h.sth.signed_bytes() in by_r and any(h.sth.verify_signature(k) for k in keys) for h in heads):
                keys.append(r)
                pending.remove(r)
                grown = True
    return keys


def verify(db: Database, against: SignedTreeHead | Sequence[SignedTreeHead | KnownHead] | None = None, *,
           public_key: Any = None, retired: Sequence[Any] = (), require_signed_to_end: bool = False) -> VerifyReport:
    """Recompute the chain, every leaf hash and the Merkle root in one streaming pass.

    With heads (`against`): each must carry a valid signature by `public_key` (or by a
    retired key handed over from it, see accepted_keys) and name this log (else
    AuthnError); the log must hold at least tree_size entries (else: truncated), and a
    consistency proof computed from the recomputed leaves must prove, against the head's
    root, that the signed log is a prefix of today's (else: rewritten/deleted/reordered).
    """
    heads: list[KnownHead] = []
    if isinstance(against, SignedTreeHead):
        heads = [KnownHead(against, "given")]
    elif against is not None:
        heads = [h if isinstance(h, KnownHead) else KnownHead(h, "given") for h in against]
    if heads:
        if public_key is None:
            raise AuthnError("verify against a signed tree head needs the log's public key")
        keys = accepted_keys(heads, public_key, retired)
        origin = log_origin(db)
        for h in heads:
            if not any(h.sth.verify_signature(k) for k in keys):
                raise AuthnError(f"signed tree head (size {h.sth.tree_size}, {h.source}): signature is not the log "
                                 "key's (forged, altered, or another log's)")
            if h.sth.origin is not None and h.sth.origin != origin:
                return VerifyReport(False, 0, GENESIS, problem=f"the signed head of size {h.sth.tree_size} "
                                    f"({h.source}) names the log {h.sth.origin}, not this one "
                                    f"({origin or 'no origin recorded'})")
    total = int(db.fetch("SELECT COUNT(*) FROM audit_log")[0][0])
    wanted: set[merkle.Range] = set()
    for h in heads:
        if h.sth.tree_size <= total:
            wanted.update(merkle.consistency_ranges(h.sth.tree_size, total))
    collector = merkle.RangeCollector(wanted, root_sizes={h.sth.tree_size for h in heads})
    push, sha, leafh = collector.push, hashlib.sha256, merkle.leaf_hash
    prev, size = GENESIS, 0
    for seq, created, kind, serial, decision, payload, prev_hash, entry_hash, stored_leaf in _rows(db):
        expected = size + 1
        if seq != expected:
            what = "missing (deleted?)" if seq > expected else "duplicated"
            return VerifyReport(False, size, prev, "", expected, f"entry {expected} is {what}")
        if prev_hash != prev:
            return VerifyReport(False, size, prev, "", seq,
                                f"entry {seq} does not link to entry {seq - 1} (reordered or rewritten)")
        body = entry_bytes(seq, _iso_db(created), kind, serial, decision, payload, prev_hash)
        if sha(body).hexdigest() != entry_hash:
            return VerifyReport(False, size, prev, "", seq, f"entry {seq} was modified (hash mismatch)")
        leaf = leafh(body)
        if stored_leaf is not None and stored_leaf != leaf.hex():
            return VerifyReport(False, size, prev, "", seq, f"entry {seq}: stored leaf hash was altered")
        push(leaf)
        prev, size = entry_hash, seq
    root = collector.root()
    if size != total:  # rows appeared or vanished while we read: report, do not guess
        return VerifyReport(False, size, prev, root.hex(), size + 1, "the log changed while it was verified")
    checked: list[str] = []
    covered = 0
    for h in sorted(heads, key=lambda h: h.sth.tree_size):
        m = h.sth.tree_size
        label = f"STH size {m} of {_when(h.sth.timestamp)} ({h.source})"
        if size < m:
            return VerifyReport(False, size, prev, root.hex(), size + 1,
                                f"log truncated: {size} entries, but the {label} signed {m}")
        proof = [collector.hashes[r] for r in merkle.consistency_ranges(m, size)]
        if not merkle.verify_consistency(m, size, h.sth.root, root, proof):
            good = max((g.sth.tree_size for g in heads if g.sth.tree_size < m
                        and collector.roots.get(g.sth.tree_size) == g.sth.root), default=0)
            where = f"entry {good + 1}" if good + 1 == m else f"entries {good + 1}..{m}"
            return VerifyReport(False, size, prev, root.hex(), good + 1,
                                f"{where} differ from what the {label} signed "
                                "(rewritten, deleted, inserted or reordered)")
        checked.append(label)
        covered = max(covered, m)
    if require_signed_to_end and heads and covered < size:  # every commit signs: a gap is a forged append
        return VerifyReport(False, size, prev, root.hex(), covered + 1,
                            f"entries {covered + 1}..{size} are covered by no signed tree head "
                            "(appended outside authn?)", checked)
    return VerifyReport(True, size, prev, root.hex(), checked=checked, unsigned=size - covered if heads else size)


# --- checkpoints -------------------------------------------------------------------------

def _verified(db: Database, places: HeadPlaces, key: LogKey) -> VerifyReport:
    report = verify(db, places.all_heads(), public_key=key.public_key,
                    retired=load_retired_keys(places.log_key))
    if not report.ok:
        raise AuthnError(f"audit log does not verify: {report.problem}")
    return report


def _sign_whole(db: Database, places: HeadPlaces, report: VerifyReport, keys: Sequence[LogKey]) -> list[SignedTreeHead]:
    """Inside no transaction: sign the verified log's head with each key (one periodic head
    per key, the last key's newest), store them, and publish them."""
    leaves = [bytes.fromhex(h) for (h,) in db.fetch("SELECT leaf_hash FROM audit_log ORDER BY seq")]
    with db.write():
        if db.dialect == "postgresql":
            db.execute("SELECT pg_advisory_xact_lock(:k)", {"k": _PG_AUDIT_LOCK})
        origin = log_origin(db, create=True)
        assert origin is not None
        frontier = merkle.Frontier()
        before_last: list[bytes] = []
        for h in leaves[:report.size]:
            before_last = frontier.hashes
            frontier.push(h)
        if frontier.root().hex() != report.root or len(leaves) != report.size:
            raise AuthnError("audit log changed during the checkpoint; run it again")
        now_ms = int(time.time() * 1000)
        edge = json.dumps({"before_last": [h.hex() for h in before_last]}) if frontier.size else None
        heads = [_store_head(db, k.sign_tree_head(frontier.size, frontier.root(), now_ms, origin), edge) for k in keys]
    write_latest_head(places.latest_file, heads[-1], places.label)
    for sth in heads:
        append_sth_log(places.sth_log, sth, places.label)
    if places.witness is not None:
        places.witness_add(heads[-1], *heads[:-1], keys=[k.public_key for k in keys])
    return heads


def checkpoint(db: Database, *, log_key: str | Path | None = None, sth_log: str | Path | None = None,
               witness: str | None = None) -> SignedTreeHead:
    """Verify the whole log against every head kept anywhere, then sign its head; stored in
    the table, the latest-head file, the STH log and the witness."""
    places = HeadPlaces.of(db, sth_log=sth_log, log_key=log_key, witness=witness)
    key = writer_key(db, places.all_heads(), log_key)
    return _sign_whole(db, places, _verified(db, places, key), [key])[-1]


def rotate_key(db: Database, *, log_key: str | Path | None = None, sth_log: str | Path | None = None,
               witness: str | None = None) -> tuple[SignedTreeHead, Path]:
    """Replace the log key on purpose: verify the log, sign its head with the old key and
    with a new one (the hand-over any verifier follows, see accepted_keys), publish both,
    append the old public key to the retired keys, keep the old private key beside it as
    `<key>.retired-<id>.pem`, and put the new key in place. Returns the head and where the
    old key went."""
    places = HeadPlaces.of(db, sth_log=sth_log, log_key=log_key, witness=witness)
    p = places.log_key
    if not p.exists():
        raise SystemFault(f"audit log key {p} does not exist: rotation needs the old key to hand over from")
    old = _log_key(p)
    report = _verified(db, places, old)
    staged = p.with_name(p.name + ".new")
    if staged.exists():
        raise SystemFault(f"{staged} exists: a rotation was interrupted; move it into place or delete it")
    create_key_file(staged)
    new = LogKey.load(staged)
    heads = _sign_whole(db, places, report, [old, new])
    retired_pem = retired_keys_path(p)
    kept = p.with_name(f"{p.name}.retired-{old.key_id[:16]}.pem")
    try:
        with open(retired_pem, "a", encoding="ascii") as fh:
            fh.write(old.public_pem())
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(p, kept)
        os.replace(staged, p)
    except OSError as exc:
        raise SystemFault(f"audit log key {p}: rotation signed but not completed ({exc.strerror}); "
                          f"the new key is {staged}") from None
    _KEYS.pop(p, None)
    return heads[-1], kept


# --- inclusion proofs --------------------------------------------------------------------

def _entry_doc(row: tuple) -> dict[str, Any]:
    seq, created, kind, serial, decision, payload, prev_hash, entry_hash, _ = row
    return {"seq": int(seq), "created_at": _iso_db(created), "kind": kind, "serial": serial,
            "decision": decision, "payload": payload, "prev_hash": prev_hash, "entry_hash": entry_hash}


def prove(db: Database, seq: int, sth: SignedTreeHead | None = None, *, log_key: str | Path | None = None,
          sth_log: str | Path | None = None) -> dict[str, Any]:
    """A self-contained inclusion proof of entry `seq` (JSON-ready): the entry as hashed,
    its leaf index, the audit path, and the STH it is proved against (the newest one
    covering it, a new checkpoint if none does, or the one given)."""
    rows = db.fetch(f"SELECT {_COLUMNS} FROM audit_log WHERE seq = :s", {"s": seq})
    if not rows:
        raise AuthnError(f"no audit entry {seq}")
    if sth is None:
        key = _log_key(log_key)
        good = [h for h in known_heads(db, sth_log=sth_log, log_key=log_key)
                if h.sth.tree_size >= seq and h.sth.verify_signature(key.public_key)]
        best = newest(good)
        sth = best.sth if best is not None else checkpoint(db, log_key=log_key, sth_log=sth_log)
    n = sth.tree_size
    if seq > n:
        raise AuthnError(f"entry {seq} is not covered by the signed tree head (size {n})")
    leaves = db.fetch("SELECT leaf_hash FROM audit_log WHERE seq <= :n ORDER BY seq", {"n": n})
    if len(leaves) != n or any(h is None for (h,) in leaves):
        raise AuthnError(f"the log does not hold the {n} entries the signed tree head covers; run `authn audit verify`")
    collector = merkle.RangeCollector(merkle.inclusion_ranges(seq - 1, n))
    for (h,) in leaves:
        collector.push(bytes.fromhex(h))
    if collector.root() != sth.root:
        raise AuthnError("the log does not match the signed tree head; run `authn audit verify`")
    entry = _entry_doc(rows[0])
    body = entry_bytes(entry["seq"], entry["created_at"], entry["kind"], entry["serial"], entry["decision"],
                       entry["payload"], entry["prev_hash"])
    if merkle.leaf_hash(body).hex() != leaves[seq - 1][0]:
        raise AuthnError(f"entry {seq} does not match its leaf hash; run `authn audit verify`")
    return {"format": PROOF_FORMAT, "entry": entry, "leaf_index": seq - 1, "tree_size": n,
            "audit_path": [collector.hashes[r].hex() for r in merkle.inclusion_ranges(seq - 1, n)],
            "sth": sth.to_dict()}


def verify_proof(doc: Any, public_key: Any) -> str:
    """Check an inclusion proof with only the log's public key; returns a one-line summary.
    Raises AuthnError naming what does not hold."""
    if not isinstance(doc, dict) or doc.get("format") != PROOF_FORMAT:
        raise AuthnError(f"not an {PROOF_FORMAT} document")
    sth = SignedTreeHead.from_dict(doc.get("sth"), "proof's signed tree head")
    if not sth.verify_signature(public_key):
        raise AuthnError("the proof's signed tree head is not signed by this public key")
    entry, index, size, path = doc.get("entry"), doc.get("leaf_index"), doc.get("tree_size"), doc.get("audit_path")
    try:
        seq = entry["seq"]
        fields = (entry["created_at"], entry["kind"], entry["serial"], entry["decision"], entry["payload"],
                  entry["prev_hash"])
        if type(seq) is not int or type(index) is not int or type(size) is not int:
            raise TypeError
        if not all(isinstance(x, str) or x is None for x in fields) or not isinstance(entry["entry_hash"], str):
            raise TypeError
        nodes = [bytes.fromhex(p) for p in path]
        if any(len(p) != 32 for p in nodes) or any(p != p.lower() for p in path):
            raise ValueError
    except (KeyError, TypeError, ValueError):
        raise AuthnError("proof: malformed entry, leaf_index, tree_size or audit_path") from None
    if size != sth.tree_size:
        raise AuthnError("proof: tree_size differs from the signed tree head's")
    if index != seq - 1:
        raise AuthnError(f"proof: leaf_index {index} is not entry {seq}'s")
    body = entry_bytes(seq, *fields)
    if hashlib.sha256(body).hexdigest() != entry["entry_hash"]:
        raise AuthnError(f"proof: entry {seq} does not match its entry_hash (altered)")
    if not merkle.verify_inclusion(index, size, merkle.leaf_hash(body), nodes, sth.root):
        raise AuthnError(f"proof: entry {seq} is not in the tree the signed tree head signed")
    return (f"ok: entry {seq} is leaf {index} of the log of {size} entries signed at {_when(sth.timestamp)} "
            f"by key {sth.log_key_id[:16]}")


# --- replay ------------------------------------------------------------------------------

@dataclass(frozen=True)
class ReplayResult:
    seq: int
    same: bool
    recorded: tuple[str | None, list[str]]
    replayed: tuple[str, list[str]]
    policy_sha256: str


def replay(db: Database, seq: int) -> ReplayResult:
    """Re-decide entry `seq` with the policy text it was decided under (from audit_policies)."""
    entry = get_entry(db, seq)
    if entry is None:
        raise AuthnError(f"no audit entry {seq}")
    if entry.kind != "decision":
        raise AuthnError(f"not replayable: entry {seq} is an error entry")
    inputs, sha = entry.payload.get("policy_input"), entry.payload.get("policy_sha256")
    if not isinstance(inputs, dict) or not isinstance(sha, str):
        raise AuthnError(f"not replayable: entry {seq} has no policy_input (written before replay was recorded)")
    try:
        serial, principal = inputs["serial"], inputs["principal"]
        resource, context = inputs["resource"], inputs["context"]
    except KeyError as exc:
        raise AuthnError(f"not replayable: entry {seq}'s policy_input has no {exc.args[0]!r}") from None
    text = get_policy(db, sha)
    if text is None:
        raise AuthnError(f"not replayable: policy {sha[:16]} of entry {seq} is not recorded in the log")
    if hashlib.sha256(text.encode()).hexdigest() != sha:
        raise SystemFault(f"recorded policy {sha[:16]} does not hash to its SHA-256 (audit_policies altered)")
    from authn.policy import PolicyEngine

    result = PolicyEngine.from_text(text, f"policy {sha[:16]}").decide(serial, principal, resource, context)
    recorded = (entry.decision, list(entry.payload.get("reasons", [])))
    replayed = (result.decision, list(result.reasons))
    return ReplayResult(seq, recorded == replayed, recorded, replayed, sha)
