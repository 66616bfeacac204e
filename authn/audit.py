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

Automatic checkpoints: `append` signs a tree head when K entries were added since the
newest one, or T seconds passed (checked at append time; nothing runs in between):
    AUTHN_AUDIT_CHECKPOINT_EVERY   K, entries (default 64)
    AUTHN_AUDIT_CHECKPOINT_SECONDS T, seconds (default 300)
It continues the tree from the newest head's stored frontier (<= 64 subtree roots) over
the stored leaf hashes added since, so a checkpoint costs O(K) hashes, not O(n). The STH
goes into `audit_tree_heads` and, after commit, as one JSON line into the STH log file
(AUTHN_AUDIT_STH_LOG, default beside the log key; see authn.logkey).

Every commit also signs the head of the whole log and writes it, after commit, to the
latest-head file beside the STH log (one small file per database, replaced, never
regressing): so the newest signed head always covers every committed entry, and a tail
deleted, an entry forged or rewritten after the last periodic STH is caught too. Before
signing, `append` checks that the log extends that latest head (same root at its size)
and refuses to append to a log that does not (SystemFault, exit 3). The files outside the
database are what make truncation and rewrites detectable: keep copies where the
database's administrators cannot write.

Policies: `append(..., policy_text=...)` stores the Cedar text once per SHA-256 in
`audit_policies` in the same transaction, so `replay` can re-decide an entry later.
"""

from __future__ import annotations

import hashlib
import json
import os
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit, urlunsplit

from authn import merkle
from authn.errors import AuthnError, SystemFault
from authn.logkey import LogKey, SignedTreeHead, append_sth_log, canonical_json, key_path, latest_head_path, \
    read_latest_head, read_sth_log, sth_log_path, write_latest_head
from registry.dbapi import Database

GENESIS = "0" * 64
_PG_AUDIT_LOCK = 0x61756469_746C6F67  # "auditlog"
ENV_EVERY = "AUTHN_AUDIT_CHECKPOINT_EVERY"
ENV_SECONDS = "AUTHN_AUDIT_CHECKPOINT_SECONDS"
DEFAULT_EVERY, DEFAULT_SECONDS = 64, 300.0
PROOF_FORMAT = "authn-inclusion-proof/1"
PAGE = 5000

Checkpoint = SignedTreeHead  # the old name of "what verify checks against"
_ENC = json.JSONEncoder(sort_keys=True, separators=(",", ":"), ensure_ascii=False, allow_nan=False)
_KEYS: dict[Path, LogKey] = {}


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


def _log_key(path: str | Path | None, create: bool = True) -> LogKey:
    p = key_path(path)
    key = _KEYS.get(p)
    if key is None:
        key = _KEYS[p] = LogKey.load(p, create=create)
    return key


def db_label(db: Database) -> str:
    """Which database an STH line vouches for: its URL, password removed, SQLite path absolute."""
    if db.dialect == "sqlite":
        rest = db.url.split(":///", 1)[1].split("?", 1)[0]
        return "sqlite:///" + str(Path(rest).expanduser().resolve())
    parts = urlsplit(db.url)
    host = parts.hostname or ""
    netloc = (f"{parts.username}@" if parts.username else "") + host + (f":{parts.port}" if parts.port else "")
    return urlunsplit(("postgresql", netloc, parts.path, "", ""))


# --- append ------------------------------------------------------------------------------

def append(db: Database, entries: Sequence[NewEntry], *, policy_text: str | None = None,
           log_key: str | Path | None = None, sth_log: str | Path | None = None,
           idempotency_key: str | None = None) -> list[Entry]:
    """Append entries in one transaction (one per check, or one per batch), serialised
    against other writers: SQLite's BEGIN IMMEDIATE, PostgreSQL's advisory lock.

    With `policy_text`, its text is recorded (once per SHA-256) and every entry's payload
    carries its `policy_sha256` (added to entries without one; a different one is refused).
    Signs and stores a tree head when one is due (see the module docstring).

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
    every = _env_number(ENV_EVERY, DEFAULT_EVERY, int)
    seconds = _env_number(ENV_SECONDS, DEFAULT_SECONDS, float)
    out: list[Entry] = []
    sth: SignedTreeHead | None = None
    due = False
    label = db_label(db)
    latest_file = latest_head_path(sth_log_path(sth_log, log_key), label)
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
            sth, due = _sign_head(db, seq - len(out), seq, every, seconds, log_key, latest_file)
    if sth is not None:
        write_latest_head(latest_file, sth, label)
        if due:
            append_sth_log(sth_log_path(sth_log, log_key), sth, label)
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


def _newest_head(db: Database) -> tuple[int, int, str] | None:
    """The newest periodic head: the one whose stored frontier the next head continues from."""
    rows = db.fetch("SELECT tree_size, timestamp_ms, frontier FROM audit_tree_heads WHERE frontier IS NOT NULL "
                    "ORDER BY tree_size DESC, id DESC LIMIT 1")
    return (int(rows[0][0]), int(rows[0][1]), str(rows[0][2])) if rows else None


_HEAD_COLUMNS = "tree_size, timestamp_ms, root_hash, log_key_id, signature"


def _head_of(row: tuple) -> SignedTreeHead:
    n, ts, root, kid, sig = row
    return SignedTreeHead.from_dict({"format": "authn-sth/1", "tree_size": int(n), "timestamp": int(ts),
                                     "root_hash": root, "log_key_id": kid, "signature": sig})


def _newest_signed(db: Database) -> SignedTreeHead | None:
    """The newest head of any kind in the database (every append transaction stores one)."""
    rows = db.fetch(f"SELECT {_HEAD_COLUMNS} FROM audit_tree_heads ORDER BY tree_size DESC, id DESC LIMIT 1")
    if not rows:
        return None
    try:
        return _head_of(rows[0])
    except AuthnError:
        raise SystemFault("audit log: the newest signed head in the database is malformed; "
                          "run `authn audit verify`") from None


def _sign_head(db: Database, size_before: int, size: int, every: int, seconds: float,
               log_key: str | Path | None, latest_file: Path) -> tuple[SignedTreeHead, bool]:
    """Inside append's transaction: sign the head of all `size` entries (every commit), and
    say whether it is also due for the table and the STH log (K entries / T seconds).

    Before signing, the log must extend the latest head signed for it (the latest-head
    file): the same root at that size. A log that was truncated, or rewritten after that
    head, is refused here (SystemFault, the transaction rolls back): the log never signs
    over tampering, and no decision is added to a tampered log."""
    key = _log_key(log_key)
    latest = read_latest_head(latest_file)
    if latest is not None and not key.vouches_for(latest):
        raise SystemFault(f"{latest_file}: the latest signed head is not signed by this log's key")
    if latest is not None and latest.tree_size > size:
        raise SystemFault(f"audit log truncated: {size} entries, but the latest signed head has "
                          f"{latest.tree_size}; run `authn audit verify`")
    signed = _newest_signed(db)
    if signed is not None and not key.vouches_for(signed):
        raise SystemFault("audit log: the newest signed head in the database is not signed by this log's key; "
                          "run `authn audit verify`")
    if signed is not None and signed.tree_size != size_before:
        what = ("truncated" if signed.tree_size > size_before else
                f"entries {signed.tree_size + 1}..{size_before} carry no signed head (written outside authn?)")
        raise SystemFault(f"audit log {what}; run `authn audit verify`")
    now_ms = int(time.time() * 1000)
    newest = _newest_head(db)
    base_size, base_ms, frontier_json = newest if newest else (0, 0, "[]")
    try:
        frontier = merkle.Frontier(base_size, [bytes.fromhex(h) for h in json.loads(frontier_json)])
    except (ValueError, TypeError):
        frontier = merkle.Frontier()  # unreadable frontier: rebuild from the leaves
    if frontier.size > size:
        raise SystemFault(f"audit log truncated: {size} entries, but a signed head in the database has "
                          f"{frontier.size}; run `authn audit verify`")
    leaves = db.fetch("SELECT leaf_hash FROM audit_log WHERE seq > :a ORDER BY seq", {"a": frontier.size})
    if len(leaves) != size - frontier.size or any(h is None for (h,) in leaves):
        raise SystemFault("audit log damaged (entries or leaf hashes missing); run `authn audit verify`")
    check_at = latest.tree_size if latest is not None and latest.tree_size >= frontier.size else None
    for (h,) in leaves:
        if frontier.size == check_at:
            _same_root(frontier, latest)
        frontier.push(bytes.fromhex(h))
    if frontier.size == check_at:
        _same_root(frontier, latest)
    sth = key.sign_tree_head(frontier.size, frontier.root(), now_ms)
    due = size - base_size >= every or now_ms - base_ms >= seconds * 1000
    _store_head(db, frontier if due else None, sth)
    return sth, due


def _same_root(frontier: merkle.Frontier, latest: SignedTreeHead) -> None:
    if frontier.root() != latest.root:
        raise SystemFault(f"audit log entries 1..{latest.tree_size} differ from the latest signed head "
                          "(rewritten, deleted or reordered); run `authn audit verify`")


def _store_head(db: Database, frontier: merkle.Frontier | None, sth: SignedTreeHead) -> SignedTreeHead:
    db.execute("INSERT INTO audit_tree_heads (tree_size, timestamp_ms, root_hash, log_key_id, signature, frontier) "
               "VALUES (:n, :t, :r, :k, :s, :f)",
               {"n": sth.tree_size, "t": sth.timestamp, "r": sth.root_hash, "k": sth.log_key_id,
                "s": sth.signature, "f": None if frontier is None else json.dumps([h.hex() for h in frontier.hashes])})
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


# --- signed tree heads we know of ----------------------------------------------------------

@dataclass(frozen=True)
class KnownHead:
    sth: SignedTreeHead
    source: str  # "file PATH" | "database" | "--against FILE"


def known_heads(db: Database, *, sth_log: str | Path | None = None, log_key: str | Path | None = None) -> list[KnownHead]:
    """STHs for this database from the external STH log and from audit_tree_heads (unverified)."""
    out: list[KnownHead] = []
    path = sth_log_path(sth_log, log_key)
    label = db_label(db)
    for owner, sth in read_sth_log(path):
        if owner == label:
            out.append(KnownHead(sth, f"file {path}"))
    latest_file = latest_head_path(path, label)
    latest = read_latest_head(latest_file)
    if latest is not None:
        out.append(KnownHead(latest, f"file {latest_file}"))
    newest_row = db.fetch("SELECT id FROM audit_tree_heads ORDER BY tree_size DESC, id DESC LIMIT 1")
    newest_id = newest_row[0][0] if newest_row else None
    for n, ts, root, kid, sig in db.fetch(f"SELECT {_HEAD_COLUMNS} FROM audit_tree_heads "
                                          "WHERE frontier IS NOT NULL OR id = :newest ORDER BY id",
                                          {"newest": newest_id if newest_id is not None else -1}):
        try:
            sth = SignedTreeHead.from_dict({"format": "authn-sth/1", "tree_size": int(n), "timestamp": int(ts),
                                            "root_hash": root, "log_key_id": kid, "signature": sig})
        except AuthnError:
            out.append(KnownHead(SignedTreeHead(int(n), int(ts), GENESIS, "", ""), "database (malformed)"))
            continue
        out.append(KnownHead(sth, "database"))
    return out


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


def verify(db: Database, against: SignedTreeHead | Sequence[SignedTreeHead | KnownHead] | None = None, *,
           public_key: Any = None, require_signed_to_end: bool = False) -> VerifyReport:
    """Recompute the chain, every leaf hash and the Merkle root in one streaming pass.

    With STHs (`against`): each must carry a valid signature by `public_key` (else
    AuthnError), the log must hold at least tree_size entries (else: truncated), and a
    consistency proof computed from the recomputed leaves must prove, against the STH's
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
        for h in heads:
            if not h.sth.verify_signature(public_key):
                raise AuthnError(f"signed tree head (size {h.sth.tree_size}, {h.source}): signature is not the log "
                                 "key's (forged, altered, or another log's)")
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

def checkpoint(db: Database, *, log_key: str | Path | None = None,
               sth_log: str | Path | None = None) -> SignedTreeHead:
    """Verify the whole log, then sign its tree head; stored in the table and the STH log file."""
    report = verify(db)
    if not report.ok:
        raise AuthnError(f"audit log does not verify: {report.problem}")
    key = _log_key(log_key)
    leaves = [bytes.fromhex(h) for (h,) in db.fetch("SELECT leaf_hash FROM audit_log ORDER BY seq")]
    with db.write():
        if db.dialect == "postgresql":
            db.execute("SELECT pg_advisory_xact_lock(:k)", {"k": _PG_AUDIT_LOCK})
        frontier = merkle.Frontier()
        for h in leaves[:report.size]:
            frontier.push(h)
        if frontier.root().hex() != report.root:
            raise AuthnError("audit log changed during the checkpoint; run it again")
        sth = _store_head(db, frontier, key.sign_tree_head(frontier.size, frontier.root(), int(time.time() * 1000)))
    append_sth_log(sth_log_path(sth_log, log_key), sth, db_label(db))
    return sth


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
