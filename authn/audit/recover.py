"""`recover`: sign a log that no trusted head vouches for, as it stands, on an operator's word.

The writer refuses to sign over entries no signed head covers (their heads deleted, the key
lost, a log from before signing): signing them would launder whatever a database writer
did to them. Recovery is that signature made on purpose: the operator names the tree root
of the entries they trust (printed by a run without it), the log must be whole as a chain
and consistent with every head still found, and the recovery is itself an entry (kind
`audit`) that says what was trusted, so the log records its own gap in custody.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import authn.audit.merkle as merkle
from authn.audit.edge import edge_json
from authn.audit.entries import NewEntry, lock
from authn.audit._internal.headrows import Signed, load_key, store_head
from authn.audit.heads import HeadPlaces, log_origin
from authn.audit.logkey import create_key_file, load_retired_keys
from authn.audit.tree_head import SignedTreeHead, canonical_json
from authn.audit.verifier import VerifyReport, verify
from authn.audit.writer import insert_entry
from core.errors import AuthnError, SystemFault
from registry.dbapi import Database


@dataclass(frozen=True)
class Recovered:
    entries: int  # the entries trusted as they stood
    root: str  # their tree root, hex
    vouched: int  # how many of them a signed head already covered
    seq: int | None  # the recovery entry (None: nothing to recover)
    head: SignedTreeHead | None = None
    new_key: bool = False


def _state(db: Database, places: HeadPlaces) -> tuple[VerifyReport, bool, bool]:
    """The log as it stands, checked against every head still found (AuthnError "does not
    verify" when it is broken or contradicts one); whether any head was found, and whether
    the key file exists."""
    heads, damage = places.all_heads_and_damage()
    if damage:
        raise AuthnError(f"audit log does not verify: {'; '.join(damage)} (move the damaged file aside first)")
    have_key = places.log_key.exists()
    if heads and not have_key:
        raise SystemFault(f"audit log key {places.log_key} is missing but signed heads of the log exist: restore the "
                          "key file (recover signs with a new key only a log that no head is left of)")
    if heads:
        report = verify(db, heads, public_key=load_key(places.log_key).public_key,
                        retired=load_retired_keys(places.log_key))
    else:
        report = verify(db)
    if not report.ok:
        raise AuthnError(f"audit log does not verify: {report.problem}")
    return report, bool(heads), have_key


def recover(db: Database, trust_root: str | None, *, log_key: str | Path | None = None,
            sth_log: str | Path | None = None, witness: str | None = None) -> Recovered:
    """Sign the log as it stands when no signed head vouches for all of it: `trust_root` must
    be its tree root (else AuthnError, naming the root and the count). Appends an `audit`
    entry recording what was trusted, signs a periodic head over everything with the log key
    (a new one when the key file is gone and no head is left), and publishes it."""
    places = HeadPlaces.of(db, sth_log=sth_log, log_key=log_key, witness=witness)
    report, signed, have_key = _state(db, places)
    vouched = report.size - report.unsigned
    if report.unsigned == 0 if signed else report.size == 0 and log_origin(db) is None:
        return Recovered(report.size, report.root, vouched, None)
    if trust_root is None or trust_root.strip().lower() != report.root:
        given = "no --trust-root given" if trust_root is None else f"--trust-root is {trust_root.strip()!r}"
        raise AuthnError(f"{given}: the log holds {report.size} entries ({vouched} vouched for by a signed head), tree "
                         f"root {report.root}; to sign them as they stand: authn audit recover --trust-root "
                         f"{report.root}")
    with db.write():
        lock(db)
        if verify(db).root != report.root:
            raise AuthnError("audit log changed during recover; run it again")
        if not have_key:
            create_key_file(places.log_key)
        key = load_key(places.log_key)
        origin = log_origin(db, create=True)
        assert origin is not None
        payload = {"action": "recover", "trusted": {"entries": report.size, "tree_root": report.root,
                                                    "chain_head": report.head, "vouched": vouched},
                   "log_key_id": key.key_id, "new_key": not have_key}
        frontier = merkle.Frontier()
        for (h,) in db.fetch("SELECT leaf_hash FROM audit_log ORDER BY seq"):
            frontier.push(bytes.fromhex(h))
        entry = insert_entry(db, report.size + 1, report.head, NewEntry("audit", None, None, payload), payload,
                             canonical_json(payload))
        before_last = frontier.hashes
        frontier.push(bytes.fromhex(str(entry.leaf_hash)))
        sth = key.sign_tree_head(frontier.size, frontier.root(), int(time.time() * 1000), origin)
        store_head(db, sth, edge_json(key, sth, before_last))
    places.publish(Signed(sth, True))
    return Recovered(report.size, report.root, vouched, entry.seq, sth, not have_key)
