"""`export`: the log as a verifier outside authn needs it: the leaf bytes of every entry its
newest checkpoint covers, that checkpoint (a C2SP signed note) and the public key.

Layout of the folder (docs/audit.md, "Export"):
    leaves.jsonl       one line per entry in seq order: {"seq": n, "leaf": base64 of its leaf bytes}
    checkpoint.txt     the newest checkpoint signed by the log key, covering exactly those entries
    log-key.pub.pem    the log's Ed25519 public key
tools/verify_audit_export.py checks such a folder with hashlib and cryptography alone.
"""

from __future__ import annotations

import base64
import json
from dataclasses import dataclass
from pathlib import Path

import authn.audit.merkle as merkle
from authn.audit._internal.headrows import load_key
from authn.audit._internal.rows import MalformedRow, rows, stored_leaf
from authn.audit.heads import known_heads, newest
from core.errors import AuthnError
from registry.dbapi import Database

LEAVES, CHECKPOINT, PUBLIC_KEY = "leaves.jsonl", "checkpoint.txt", "log-key.pub.pem"


class NotExportable(AuthnError):
    """The stored log does not make the tree its newest checkpoint signed (`audit export` exit 1)."""


@dataclass(frozen=True)
class Exported:
    entries: int
    root: str  # hex
    folder: Path


def export(db: Database, folder: Path, *, log_key: str | Path | None = None,
           sth_log: str | Path | None = None) -> Exported:
    """Write the export into `folder` (made if missing; its three files replaced). Refuses
    when no checkpoint of this key exists (AuthnError) or the stored entries do not make the
    tree it signed (NotExportable): nothing is exported that would not verify."""
    key = load_key(log_key)
    signed = [h for h in known_heads(db, sth_log=sth_log, log_key=log_key)
              if h.sth.origin is not None and h.sth.verify_signature(key.public_key)]
    head = newest(signed)
    if head is None:
        raise AuthnError("the audit log has no checkpoint signed by its key yet: run `authn audit checkpoint`")
    n = head.sth.tree_size
    bodies: list[bytes] = []
    try:
        for row in rows(db):
            if len(bodies) == n:
                break
            bodies.append(stored_leaf(row))
    except MalformedRow as exc:
        raise NotExportable(f"audit log entry {len(bodies) + 1}: {exc}; run `authn audit verify`") from None
    root = merkle.root_hash([merkle.leaf_hash(b) for b in bodies])
    if len(bodies) != n or root != head.sth.root:
        raise NotExportable(f"the stored entries do not make the tree the newest checkpoint (size {n}) signed; "
                         "run `authn audit verify`")
    try:
        folder.mkdir(parents=True, exist_ok=True)
        lines = (json.dumps({"seq": i, "leaf": base64.b64encode(b).decode()}) + "\n" for i, b in enumerate(bodies, 1))
        (folder / LEAVES).write_text("".join(lines), encoding="ascii")
        (folder / CHECKPOINT).write_text(head.sth.note(), encoding="utf-8")
        (folder / PUBLIC_KEY).write_text(key.public_pem(), encoding="ascii")
    except OSError as exc:
        raise AuthnError(f"{folder}: cannot write the export ({exc.strerror})") from None
    return Exported(n, root.hex(), folder)
