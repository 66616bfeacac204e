"""Heads signed on demand: `checkpoint` (verify everything, then sign a periodic head)
and `rotate_key` (the same, signed by the old key and a new one, then the key replaced)."""

from __future__ import annotations

import os
import time
from collections.abc import Sequence
from pathlib import Path

import authn.audit.merkle as merkle
from authn.audit.edge import edge_json
from authn.audit.entries import lock
from authn.audit._internal.headrows import KEYS, load_key, store_head
from authn.audit.heads import HeadPlaces, log_origin, writer_key
from authn.audit.head_files import append_sth_log, write_latest_head
from authn.audit.logkey import LogKey, create_key_file, load_retired_keys, retired_keys_path
from authn.audit.tree_head import SignedTreeHead
from authn.audit.verifier import VerifyReport, verify
from core.errors import AuthnError, SystemFault
from registry.dbapi import Database

def _verified(db: Database, places: HeadPlaces, key: LogKey) -> VerifyReport:
    """The log verified against every head kept anywhere, each head source readable, and every
    entry covered by a signed head (else AuthnError: nothing is signed over it)."""
    heads, damage = places.all_heads_and_damage()
    if damage:
        raise AuthnError(f"audit log does not verify: {'; '.join(damage)}")
    report = verify(db, heads, public_key=key.public_key, retired=load_retired_keys(places.log_key),
                    require_signed_to_end=True)
    if not report.ok:
        raise AuthnError(f"audit log does not verify: {report.problem}")
    return report



def _sign_whole(db: Database, places: HeadPlaces, report: VerifyReport, keys: Sequence[LogKey]) -> list[SignedTreeHead]:
    """Inside no transaction: sign the verified log's head with each key (one periodic head
    per key, the last key's newest), store them, and publish them."""
    leaves = [bytes.fromhex(h) for (h,) in db.fetch("SELECT leaf_hash FROM audit_log ORDER BY seq")]
    with db.write():
        lock(db)
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
        heads = []
        for k in keys:
            sth = k.sign_tree_head(frontier.size, frontier.root(), now_ms, origin)
            heads.append(store_head(db, sth, edge_json(k, sth, before_last) if frontier.size else None))
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
    old = load_key(p)
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
    KEYS.pop(p, None)
    return heads[-1], kept
