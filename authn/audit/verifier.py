"""`verify`: recompute the whole log (chain, leaves, Merkle root) in one streaming pass and
prove it extends every signed head given, by RFC 9162 consistency proofs."""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from dataclasses import dataclass, field
from datetime import datetime, timezone
from typing import Any

import authn.audit.merkle as merkle
from authn.audit.entries import GENESIS, _iso_db, _rows, entry_bytes
from authn.audit.heads import KnownHead, accepted_keys, log_origin
from authn.audit.logkey import SignedTreeHead
from core.errors import AuthnError
from registry.dbapi import Database

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
