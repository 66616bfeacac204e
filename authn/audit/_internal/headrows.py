"""Signed heads as the audit modules share them: a head and where it was found, its row in
`audit_tree_heads`, the checks a trusted head must pass, the log key loaded once per file
version, and a head's time as reports print it."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from authn.audit.logkey import LogKey, key_path
from authn.audit.tree_head import CHECKPOINT_FORMAT, SignedTreeHead
from core.errors import SystemFault
from registry.dbapi import Database

HEAD_COLUMNS = "tree_size, timestamp_ms, root_hash, log_key_id, signature, origin"

#: loaded log keys by path: (file version, key)
KEYS: dict[Path, tuple[tuple[int, int] | None, LogKey]] = {}


@dataclass(frozen=True)
class KnownHead:
    """A signed head and where it was found (authn.audit.heads gathers them)."""

    sth: SignedTreeHead
    source: str  # "database" | "file PATH" | "witness W" | "--against FILE"


@dataclass(frozen=True)
class Signed:
    """A head the writer signed, and whether it is periodic (also to the STH log and the witness)."""

    sth: SignedTreeHead
    due: bool


def load_key(path: str | Path | None) -> LogKey:
    """The key at `path`, loaded once per file version (a replaced file is loaded again)."""
    p = key_path(path)
    try:
        st = p.stat()
        version = (st.st_ino, st.st_mtime_ns)
    except OSError:
        version = None
    cached = KEYS.get(p)
    if cached is None or cached[0] != version or version is None:
        KEYS[p] = (version, LogKey.load(p))
    return KEYS[p][1]


def head_of(row: Sequence[Any]) -> SignedTreeHead:
    """A head from a row of HEAD_COLUMNS (AuthnError when malformed)."""
    n, ts, root, kid, sig, origin = row
    fmt = "authn-sth/1" if origin is None else CHECKPOINT_FORMAT
    return SignedTreeHead.from_dict({"format": fmt, "tree_size": int(n), "timestamp": int(ts), "root_hash": root,
                                     "log_key_id": str(kid).strip(), "signature": sig, "origin": origin})


def store_head(db: Database, sth: SignedTreeHead, edge: str | None) -> SignedTreeHead:
    """Insert a signed head (with its signed right edge when periodic) into audit_tree_heads."""
    db.execute("INSERT INTO audit_tree_heads (tree_size, timestamp_ms, root_hash, log_key_id, signature, frontier, "
               "origin) VALUES (:n, :t, :r, :k, :s, :f, :o)",
               {"n": sth.tree_size, "t": sth.timestamp, "r": sth.root_hash, "k": sth.log_key_id,
                "s": sth.signature, "f": edge, "o": sth.origin})
    return sth


def check_head(h: KnownHead, key: LogKey, origin: str, size_before: int) -> None:
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


def when(ms: int) -> str:
    """A head's timestamp (ms since the epoch) as reports print it."""
    return datetime.fromtimestamp(ms / 1000, timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")
