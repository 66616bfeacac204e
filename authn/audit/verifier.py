"""`verify`: recompute the whole log (chain, leaves, Merkle root) in one streaming pass and
prove it extends every signed head given, by RFC 9162 consistency proofs.

When something does not hold, a second pass names the first entry that differs from what
was signed: every append signs a head and keeps it in the database, so the largest signed
head whose root the recomputed log still has, and the smallest it no longer has, pin the
first changed entry (to one entry when the appends were one entry each). A break that no
signed head pins is reported where the chain breaks."""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import authn.audit.merkle as merkle
from authn.audit._internal.headrows import HEAD_COLUMNS, head_of, when
from authn.audit._internal.rows import ColumnsAltered, MalformedRow, rows, stored_leaf
from authn.audit.entries import GENESIS
from authn.audit.heads import KnownHead, accepted_keys, log_origin
from authn.audit.tree_head import SignedTreeHead
from core.errors import AuthnError
from registry.dbapi import Database

if TYPE_CHECKING:
    from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PublicKey

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



def _leaf(row: Sequence[Any]) -> tuple[bytes, bytes | None, str | None]:
    """A row's leaf hash and stored leaf bytes (its columns agreeing with them), or a leaf no
    entry has and what is wrong."""
    try:
        body = stored_leaf(row)
    except MalformedRow as exc:
        what = f"was modified ({exc})" if isinstance(exc, ColumnsAltered) else f"is malformed: {exc}"
        return hashlib.sha256(b"\xffmalformed" + str(row[0]).encode()).digest(), None, what
    return merkle.leaf_hash(body), body, None


def _row_problem(row: Sequence[Any], expected: int, prev: str, body: bytes | None, leaf: bytes,
                 malformed: str | None) -> str | None:
    """What is wrong with the row at position `expected` on its own (None: nothing)."""
    seq, stored_hash, stored_leaf = row[0], row[7], row[8]
    if seq != expected:
        if type(seq) is not int:
            return f"entry {expected}: seq is not an integer"
        return f"entry {expected} is {'missing (deleted?)' if seq > expected else 'duplicated'}"
    if malformed is not None or body is None:
        return f"entry {seq} {malformed}"
    if row[6] != prev:
        return (f"entry {seq} does not link to entry {seq - 1} (entry {seq - 1} or an earlier one rewritten, "
                "or entries reordered)")
    if hashlib.sha256(body).hexdigest() != stored_hash:
        return f"entry {seq} was modified (hash mismatch)"
    if stored_leaf is None:
        return f"entry {seq}: stored leaf hash is missing"
    if stored_leaf != leaf.hex():
        return f"entry {seq}: stored leaf hash was altered"
    return None


def _signed(h: KnownHead, keys: Sequence[Ed25519PublicKey]) -> bool:
    return any(h.sth.verify_signature(k) for k in keys)


def _pin(db: Database, heads: Sequence[KnownHead], keys: Sequence[Ed25519PublicKey],
         size: int) -> tuple[int, int, str] | None:
    """(g, m, label): the largest signed head size g whose root the recomputed log has below
    the smallest signed head size m whose root it has not (label: m's head), over every head
    in the database and those given; None when every signed head up to `size` holds."""
    by_size: dict[int, list[KnownHead]] = {}
    candidates = list(heads)
    if keys:
        for row in db.fetch(f"SELECT {HEAD_COLUMNS} FROM audit_tree_heads WHERE tree_size <= :n", {"n": size}):
            try:
                candidates.append(KnownHead(head_of(row), "database"))
            except AuthnError:
                continue
    for h in candidates:
        if 0 < h.sth.tree_size <= size:
            by_size.setdefault(h.sth.tree_size, []).append(h)
    if not by_size:
        return None
    collector = merkle.RangeCollector(root_sizes=by_size)
    for row in rows(db):
        collector.push(_leaf(row)[0])
    roots = collector.roots
    sizes = sorted(by_size)
    bad = next(((n, h) for n in sizes for h in by_size[n] if roots.get(n) != h.sth.root and _signed(h, keys)), None)
    if bad is None:
        return None
    m, head = bad
    good = next((n for n in reversed(sizes) if n < m and any(roots.get(n) == h.sth.root and _signed(h, keys)
                                                              for h in by_size[n])), 0)
    return good, m, f"STH size {m} of {when(head.sth.timestamp)} ({head.source})"


def _failure(db: Database, heads: Sequence[KnownHead], keys: Sequence[Ed25519PublicKey], size: int,
             local: tuple[int, str] | None, other: tuple[int, str] | None) -> tuple[int, str]:
    """The first bad entry and the one-line problem: the signed heads' pin when it is at or
    before the local break (the break is named too), else the break, else the head's own."""
    pinned = _pin(db, heads, keys, size)
    if pinned is not None:
        good, m, label = pinned
        if local is None or m <= local[0]:
            where = f"entry {m}" if good + 1 == m else f"entries {good + 1}..{m}"
            problem = f"{where} differ{'s' if good + 1 == m else ''} from what the {label} signed"
            return good + 1, problem + (f"; {local[1]}" if local is not None else
                                        " (rewritten, deleted, inserted or reordered)")
    found = local or other
    assert found is not None
    return found


def verify(db: Database, against: SignedTreeHead | Sequence[SignedTreeHead | KnownHead] | None = None, *,
           public_key: Ed25519PublicKey | None = None, retired: Sequence[Ed25519PublicKey] = (),
           require_signed_to_end: bool = False) -> VerifyReport:
    """Recompute the chain, every leaf hash (and compare the stored ones) and the Merkle root
    in one streaming pass.

    With heads (`against`): each must carry a valid signature by `public_key` (or by a
    retired key handed over from it, see accepted_keys) and name this log (else
    AuthnError); the log must hold at least tree_size entries (else: truncated), and a
    consistency proof computed from the recomputed leaves must prove, against the head's
    root, that the signed log is a prefix of today's (else: rewritten/deleted/reordered).
    With `require_signed_to_end`, entries that no head covers (none at all included) fail.
    A failure names the first entry that differs (see the module docstring).
    """
    heads: list[KnownHead] = []
    if isinstance(against, SignedTreeHead):
        heads = [KnownHead(against, "given")]
    elif against is not None:
        heads = [h if isinstance(h, KnownHead) else KnownHead(h, "given") for h in against]
    keys: list[Ed25519PublicKey] = []
    if heads:
        if public_key is None:
            raise AuthnError("verify against a signed tree head needs the log's public key")
        keys = accepted_keys(heads, public_key, retired)
        origin = log_origin(db)
        for h in heads:
            if not _signed(h, keys):
                raise AuthnError(f"signed tree head (size {h.sth.tree_size}, {h.source}): signature is not the log "
                                 "key's (forged, altered, or another log's)")
            if h.sth.origin is not None and h.sth.origin != origin:
                return VerifyReport(False, 0, GENESIS, problem=f"the signed head of size {h.sth.tree_size} "
                                    f"({h.source}) names the log {h.sth.origin}, not this one "
                                    f"({origin or 'no origin recorded'})")
    elif public_key is not None:
        keys = accepted_keys([], public_key, retired)
    total = int(db.fetch("SELECT COUNT(*) FROM audit_log")[0][0])
    wanted: set[merkle.Range] = set()
    for h in heads:
        if h.sth.tree_size <= total:
            wanted.update(merkle.consistency_ranges(h.sth.tree_size, total))
    collector = merkle.RangeCollector(wanted, root_sizes={h.sth.tree_size for h in heads})
    prev, size, local = GENESIS, 0, None
    for row in rows(db):
        leaf, body, malformed = _leaf(row)
        if local is None:
            problem = _row_problem(row, size + 1, prev, body, leaf, malformed)
            local = (size + 1, problem) if problem is not None else None
        collector.push(leaf)
        prev, size = row[7], size + 1
    root = collector.root()
    if size != total:  # rows appeared or vanished while we read: report, do not guess
        return VerifyReport(False, size, prev, root.hex(), size + 1, "the log changed while it was verified")
    checked, other, covered = _check_heads(heads, collector, size)
    if local is None and other is None and require_signed_to_end and covered < size:
        return VerifyReport(False, size, prev, root.hex(), covered + 1,
                            f"entries {covered + 1}..{size} are covered by no signed tree head (appended outside "
                            "authn, or their heads deleted; `authn audit recover` signs the log as it stands)",
                            checked)
    if local is not None or other is not None:
        first, problem = _failure(db, heads, keys, size, local, other)
        return VerifyReport(False, size, prev, root.hex(), first, problem, checked)
    return VerifyReport(True, size, prev, root.hex(), checked=checked, unsigned=size - covered if heads else size)


def _check_heads(heads: Sequence[KnownHead], collector: merkle.RangeCollector,
                 size: int) -> tuple[list[str], tuple[int, str] | None, int]:
    """Each head against the recomputed log: (labels of those it extends, the first failure
    as (first bad entry, problem), the largest size covered)."""
    checked: list[str] = []
    covered = 0
    root = collector.root()
    for h in sorted(heads, key=lambda h: h.sth.tree_size):
        m = h.sth.tree_size
        label = f"STH size {m} of {when(h.sth.timestamp)} ({h.source})"
        if size < m:
            return checked, (size + 1, f"log truncated: {size} entries, but the {label} signed {m}"), covered
        proof = [collector.hashes[r] for r in merkle.consistency_ranges(m, size)]
        if not merkle.verify_consistency(m, size, h.sth.root, root, proof):
            good = max((g.sth.tree_size for g in heads if g.sth.tree_size < m
                        and collector.roots.get(g.sth.tree_size) == g.sth.root), default=0)
            where = f"entry {good + 1}" if good + 1 == m else f"entries {good + 1}..{m}"
            return checked, (good + 1, f"{where} differ from what the {label} signed "
                             "(rewritten, deleted, inserted or reordered)"), covered
        checked.append(label)
        covered = max(covered, m)
    return checked, None, covered
