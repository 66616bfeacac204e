"""Tamper-evident audit log of decisions: a hash chain whose entries are the leaves of an
RFC 9162 Merkle tree, with signed heads (C2SP checkpoints) kept outside the database.

Why both: the chain (entry_hash = SHA-256(canonical entry), each entry naming the previous
one's hash) finds the first bad row by itself; the tree gives what the chain cannot --
short inclusion proofs a third party checks with only the log's public key, and
consistency proofs that today's log extends the one an old head signed. Neither uses a
secret, so only signatures protect against someone who can write the database: a head
signed by the log key (a file the database never holds) and kept elsewhere fixes the
first tree_size entries.

Modules, each with one job:
    log       AuditLog, the one way the product records: a decision, an error, a registry change
    leaf      the leaf bytes: what is stored and hashed (versioned, docs/audit.md)
    entries   the entries recorded and read back
    export    the log's leaf bytes and newest checkpoint, for a verifier outside authn
    writer    append: prove the log extends every trusted head, then sign the new one
    heads     where heads are kept and which are trusted (database, files, witness), the
              log's origin, the writer's key, the hand-over rule for retired keys
    signer    checkpoint and rotate_key: heads signed on demand
    recover   sign a log no trusted head vouches for, as it stands, on an operator's word
    edge      the signed right edge a periodic head keeps (where the writer's proof starts)
    verifier  verify: the whole log against every head
    proofs    inclusion proofs, checked with only the public key
    replay    re-decide an entry under the policy text it was decided with
    logkey    the Ed25519 log key: its file, path and retired keys
    tree_head signed tree heads: C2SP checkpoints and legacy authn-sth/1 heads
    head_files  the STH log and the latest-head file that keep heads outside the database
    witness   heads kept on another host, each proven to extend the last
    witness_http  the witness served over HTTP (uvicorn, as `authn serve`)
    merkle    RFC 9162 hashing and proofs
    _internal what the modules share: stored rows, heads as rows (never imported outside the package)
"""

from importlib import import_module
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # what __getattr__ loads, as type checkers should see it (a test holds the two equal)
    from authn.audit.entries import (GENESIS, Entry, NewEntry, batch_entries, db_label, get_entry, get_policy,
                                     list_entries)
    from authn.audit.export import export
    from authn.audit.heads import (HeadPlaces, KnownHead, accepted_keys, consistency_proof, known_heads,
                                   log_origin, newest, writer_key)
    from authn.audit.log import AuditLog
    from authn.audit.proofs import PROOF_FORMAT, prove, verify_proof
    from authn.audit.recover import Recovered, recover
    from authn.audit.replay import ReplayResult, replay
    from authn.audit.signer import checkpoint, rotate_key
    from authn.audit.verifier import VerifyReport, verify
    from authn.audit.writer import append

#: the public API, by the module that defines it: loaded on first use (PEP 562), so a check,
#: which needs only the writer, does not import the verifier, the prover or the witness client
_WHERE = {
    "entries": ("GENESIS", "Entry", "NewEntry", "batch_entries", "db_label", "get_entry", "get_policy",
                "list_entries"),
    "export": ("export",),
    "log": ("AuditLog",),
    "heads": ("HeadPlaces", "KnownHead", "accepted_keys", "consistency_proof", "known_heads", "log_origin", "newest",
              "writer_key"),
    "proofs": ("PROOF_FORMAT", "prove", "verify_proof"),
    "recover": ("Recovered", "recover"),
    "replay": ("ReplayResult", "replay"),
    "signer": ("checkpoint", "rotate_key"),
    "verifier": ("VerifyReport", "verify"),
    "writer": ("append",),
}
_MODULE_OF = {name: module for module, names in _WHERE.items() for name in names}
__all__ = sorted(_MODULE_OF)


def __getattr__(name: str) -> object:
    module = _MODULE_OF.get(name)
    if module is None:
        raise AttributeError(f"module 'authn.audit' has no attribute {name!r}")
    value = getattr(import_module(f"authn.audit.{module}"), name)
    globals()[name] = value
    return value
