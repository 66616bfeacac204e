"""Inclusion proofs: `prove` one entry against a signed head, and `verify_proof` with only
the log's public key (no database)."""

from __future__ import annotations

import base64
import binascii
import hashlib
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import authn.audit.merkle as merkle
from authn.audit._internal.headrows import load_key, when
from authn.audit import leaf
from authn.audit._internal.rows import COLUMNS, MalformedRow, stored_leaf, utc_text
from authn.audit.heads import known_heads, newest
from authn.audit.tree_head import SignedTreeHead
from authn.audit.signer import checkpoint
from core.errors import AuthnError
from registry.dbapi import Database

if TYPE_CHECKING:
    from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PublicKey

PROOF_FORMAT = "authn-inclusion-proof/2"
PROOF_FORMAT_V1 = "authn-inclusion-proof/1"  # no leaf bytes: the entry's version 0 bytes rebuilt from its fields


def _entry_doc(row: Sequence[Any]) -> tuple[dict[str, Any], bytes]:
    """The entry's readable fields (created_at as its leaf bytes write it) and its leaf bytes."""
    body = stored_leaf(row)
    seq, created, kind, serial, decision, payload, prev_hash, entry_hash = row[:8]
    when = utc_text(created) + ("Z" if leaf.version(body) == 1 else "+00:00")
    return ({"seq": int(seq), "created_at": when, "kind": kind, "serial": serial, "decision": decision,
             "payload": payload, "prev_hash": prev_hash, "entry_hash": entry_hash}, body)



def prove(db: Database, seq: int, sth: SignedTreeHead | None = None, *, log_key: str | Path | None = None,
          sth_log: str | Path | None = None) -> dict[str, Any]:
    """A self-contained inclusion proof of entry `seq` (JSON-ready): the entry as hashed,
    its leaf index, the audit path, and the STH it is proved against (the newest one
    covering it, a new checkpoint if none does, or the one given)."""
    rows = db.fetch(f"SELECT {COLUMNS} FROM audit_log WHERE seq = :s", {"s": seq})
    if not rows:
        raise AuthnError(f"no audit entry {seq}")
    if sth is None:
        key = load_key(log_key)
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
    try:
        entry, body = _entry_doc(rows[0])
    except MalformedRow as exc:
        raise AuthnError(f"entry {seq} is malformed ({exc}); run `authn audit verify`") from None
    if merkle.leaf_hash(body).hex() != leaves[seq - 1][0]:
        raise AuthnError(f"entry {seq} does not match its leaf hash; run `authn audit verify`")
    return {"format": PROOF_FORMAT, "entry": entry, "leaf_bytes": base64.b64encode(body).decode(),
            "leaf_index": seq - 1, "tree_size": n,
            "audit_path": [collector.hashes[r].hex() for r in merkle.inclusion_ranges(seq - 1, n)],
            "sth": sth.to_dict()}



def verify_proof(doc: object, public_key: Ed25519PublicKey) -> str:
    """Check an inclusion proof with only the log's public key; returns a one-line summary.
    Raises AuthnError naming what does not hold."""
    if not isinstance(doc, dict) or doc.get("format") not in (PROOF_FORMAT, PROOF_FORMAT_V1):
        raise AuthnError(f"not an {PROOF_FORMAT} document")
    sth = SignedTreeHead.from_dict(doc.get("sth"), "proof's signed tree head")
    if not sth.verify_signature(public_key):
        raise AuthnError("the proof's signed tree head is not signed by this public key")
    try:
        entry, index, size, path = doc["entry"], doc["leaf_index"], doc["tree_size"], doc["audit_path"]
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
        body = _proof_leaf(doc, seq, fields)
    except (KeyError, TypeError, ValueError, binascii.Error):
        raise AuthnError("proof: malformed entry, leaf_bytes, leaf_index, tree_size or audit_path") from None
    if size != sth.tree_size:
        raise AuthnError("proof: tree_size differs from the signed tree head's")
    if index != seq - 1:
        raise AuthnError(f"proof: leaf_index {index} is not entry {seq}'s")
    if body != (leaf.encode if leaf.version(body) == 1 else leaf.encode_v0)(seq, *fields):
        raise AuthnError(f"proof: entry {seq}'s fields disagree with its leaf bytes (altered)")
    if hashlib.sha256(body).hexdigest() != entry["entry_hash"]:
        raise AuthnError(f"proof: entry {seq} does not match its entry_hash (altered)")
    if not merkle.verify_inclusion(index, size, merkle.leaf_hash(body), nodes, sth.root):
        raise AuthnError(f"proof: entry {seq} is not in the tree the signed tree head signed")
    return (f"ok: entry {seq} is leaf {index} of the log of {size} entries signed at {when(sth.timestamp)} "
            f"by key {sth.log_key_id[:16]}")


def _proof_leaf(doc: dict[str, Any], seq: int, fields: tuple[str, str, str | None, str | None, str, str]) -> bytes:
    """The proved leaf bytes: as the proof carries them (base64), or, in a version 1 proof,
    rebuilt from the entry's fields in the version 0 encoding (ValueError when malformed)."""
    if doc["format"] == PROOF_FORMAT_V1:
        return leaf.encode_v0(seq, *fields)
    text = doc["leaf_bytes"]
    if not isinstance(text, str):
        raise TypeError
    body = base64.b64decode(text, validate=True)
    if leaf.version(body) is None:
        raise ValueError
    return body
