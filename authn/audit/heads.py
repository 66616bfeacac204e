"""Where the audit log's signed heads are kept, and which ones are trusted.

A head lives in the database (`audit_tree_heads`), the latest-head file, the STH log and
the witness. The writer trusts the newest of each (authn.audit.writer); `verify` checks
every one. Both read them here, so they agree on the set. Also here: the log's origin
(the name its checkpoints carry), the log key as the writer loads it (never created for
a signed log), and the hand-over rule for retired keys.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import authn.audit.merkle as merkle
from authn.audit._internal.headrows import HEAD_COLUMNS, KnownHead, Signed, head_of, load_key
from authn.audit.entries import GENESIS, db_label
from authn.audit.head_files import (append_sth_log, latest_head_path, newest_in_sth_log, read_latest_head,
                                    scan_sth_log, sth_log_path, write_latest_head)
from authn.audit.logkey import LogKey, create_key_file, key_path
from authn.audit.tree_head import SignedTreeHead, check_origin
from core.errors import AuthnError, SystemFault, one_line
from core.parsing import loads_json
from core.settings import current
from registry.dbapi import Database

if TYPE_CHECKING:
    from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PublicKey

    from authn.audit.witness import HttpWitness, WitnessStore


def writer_key(db: Database, heads: Sequence["KnownHead"], log_key: str | Path | None = None, *,
               size: int | None = None) -> LogKey:
    """The log key; created only for a new log: no signed head anywhere, no entry (of the
    first `size`: the writer's own are not yet history), no origin. Otherwise a missing key
    is a fault: a new key would let whoever made it sign history
    (`authn audit recover` does so on purpose, naming what it trusts)."""
    p = key_path(log_key)
    if not p.exists():
        held = "signed heads" if heads or db.fetch("SELECT tree_size FROM audit_tree_heads LIMIT 1") else \
            "entries" if db.fetch("SELECT seq FROM audit_log" + ("" if size is None else f" WHERE seq <= {int(size)}")
                                  + " LIMIT 1") or log_origin(db) is not None else None
        if held is not None:
            advice = ("a new one is never made for a signed log; `authn audit rotate-key` changes it" if held ==
                      "signed heads" else "if it is lost, `authn audit recover` signs the log as it stands")
            raise SystemFault(f"audit log key {p} is missing but the log has {held}: restore the key file ({advice})")
        create_key_file(p)
    return load_key(p)


def log_origin(db: Database, *, create: bool = False) -> str | None:
    """The name this log's checkpoints carry (audit_log_meta), made once inside the first
    append's transaction: $AUTHN_AUDIT_ORIGIN, else authn.invalid/audit/<random>."""
    rows = db.fetch("SELECT value FROM audit_log_meta WHERE name = 'origin'")
    if rows:
        return str(rows[0][0])
    if not create:
        return None
    import secrets  # once per log: a check that appends to an existing one never imports it

    origin = current().audit_origin or f"authn.invalid/audit/{secrets.token_hex(8)}"
    try:
        check_origin(origin)
    except ValueError:
        raise AuthnError("$AUTHN_AUDIT_ORIGIN: not a checkpoint origin "
                         "(no spaces, '+' or control characters)") from None
    db.execute("INSERT INTO audit_log_meta (name, value) VALUES ('origin', :v)", {"v": origin})
    return origin



def accepted_keys(heads: Sequence[KnownHead], current: Ed25519PublicKey,
                  retired: Sequence[Ed25519PublicKey] = ()) -> list[Ed25519PublicKey]:
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
        return cls(db, label, path, latest_head_path(path, label), key_path(log_key), _witness(witness))

    def _db_heads(self, where: str, params: dict[str, Any] | None = None) -> list[KnownHead]:
        out = []
        for row in self.db.fetch(f"SELECT {HEAD_COLUMNS} FROM audit_tree_heads {where}", params or {}):
            try:
                out.append(KnownHead(head_of(row), "database"))
            except AuthnError:
                out.append(KnownHead(SignedTreeHead(int(row[0]), int(row[1]), GENESIS, "", ""),
                                     "database (malformed)"))
        return out

    def newest_heads(self) -> list[KnownHead]:
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
        heads, damage = self.all_heads_and_damage()
        for problem in damage:
            if problem.startswith("latest-head file"):
                raise SystemFault(problem)
        return heads

    def all_heads_and_damage(self) -> tuple[list[KnownHead], list[str]]:
        """all_heads, and one line for each head source that is there but does not read as
        heads: STH log lines that are not signed heads, a latest-head file that does not parse."""
        damage: list[str] = []
        logged, bad = scan_sth_log(self.sth_log)
        if bad:
            damage.append(f"STH log {self.sth_log}: {len(bad)} of {len(bad) + len(logged)} lines are not signed "
                          f"heads (first: line {bad[0]})")
        out = [KnownHead(sth, f"file {self.sth_log}") for owner, sth in logged if owner == self.label]
        try:
            latest = read_latest_head(self.latest_file)
        except SystemFault as exc:
            damage.append(f"latest-head file {exc}")
            latest = None
        if latest is not None:
            out.append(KnownHead(latest, f"file {self.latest_file}"))
        newest_id = self.db.fetch("SELECT id FROM audit_tree_heads ORDER BY tree_size DESC, id DESC LIMIT 1")
        out += self._db_heads("WHERE frontier IS NOT NULL OR id = :newest ORDER BY id",
                              {"newest": newest_id[0][0] if newest_id else -1})
        origin = log_origin(self.db)
        if self.witness is not None and origin is not None:
            out += self.witness_heads(origin, newest_only=False)
        return out, damage

    def witness_heads(self, origin: str, *, newest_only: bool) -> list[KnownHead]:
        assert self.witness is not None
        if newest_only:
            last = self.witness.newest(origin)
            held = [last] if last is not None else []
        else:
            held = self.witness.heads(origin)
        return [KnownHead(h, f"witness {self.witness.name}") for h in held]

    def publish(self, signed: Signed) -> None:
        """After commit: the latest-head file always; periodic heads to the STH log and the witness."""
        write_latest_head(self.latest_file, signed.sth, self.label)
        if not signed.due:
            return
        append_sth_log(self.sth_log, signed.sth, self.label)
        if self.witness is not None:
            self.witness_add(signed.sth)

    def witness_add(self, sth: SignedTreeHead, *cosigned: SignedTreeHead,
                    keys: Sequence[Ed25519PublicKey] = ()) -> None:
        """Give the witness `sth` with a consistency proof from the newest head it holds. A
        refusal is a fault (it holds history this log no longer has); an unreachable
        witness is only reported: the next periodic head carries the proof from where it is."""
        from authn.audit.witness import Conflict

        assert self.witness is not None and sth.origin is not None
        try:
            held = self.witness.newest(sth.origin)
            old = held.tree_size if held is not None else 0
            proof = consistency_proof(self.db, old, sth.tree_size)
            for head in (sth, *cosigned):
                self.witness.add(head, old, proof, list(keys) or [load_key(self.log_key).public_key])
        except Conflict as exc:
            raise SystemFault(f"witness {self.witness.name} refused the head of size {sth.tree_size}: {exc}") from None
        except SystemFault as exc:
            print(f"authn: warning: {one_line(exc)}; the witness gets the next periodic head", file=sys.stderr)



def _witness(spec: str | None) -> WitnessStore | HttpWitness | None:
    """--witness, else $AUTHN_AUDIT_WITNESS (authn.audit.witness, loaded only when one is set)."""
    if not (spec or current().audit_witness):
        return None
    from authn.audit.witness import open_witness

    return open_witness(spec)


def consistency_proof(db: Database, old: int, new: int) -> list[bytes]:
    """PROOF(old, new) over the stored leaf hashes: from the right edge stored with a periodic
    head of size `old` (O(new - old + log new)), else one pass over the leaves."""
    if old == 0 or old == new:
        return []
    frontier: merkle.Frontier | None = None
    rows = db.fetch("SELECT frontier FROM audit_tree_heads WHERE tree_size = :n AND frontier IS NOT NULL "
                    "ORDER BY id DESC LIMIT 1", {"n": old})
    try:
        edge = loads_json(rows[0][0]) if rows else None
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
