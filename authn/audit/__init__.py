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
    entries   the canonical entry bytes, the rows, reading them back
    writer    append: prove the log extends every trusted head, then sign the new one
    heads     where heads are kept and which are trusted (database, files, witness), the
              log's origin, the writer's key, the hand-over rule for retired keys
    signer    checkpoint and rotate_key: heads signed on demand
    verifier  verify: the whole log against every head
    proofs    inclusion proofs, checked with only the public key
    replay    re-decide an entry under the policy text it was decided with
    logkey    the Ed25519 log key and the checkpoint format
    witness   heads kept on another host, each proven to extend the last
    merkle    RFC 9162 hashing and proofs
"""

from authn.audit.entries import GENESIS, Entry, NewEntry, _iso_db, batch_entries, compute_hash, db_label, entry_bytes, \
    get_entry, get_policy, list_entries
from authn.audit.heads import HeadPlaces, KnownHead, accepted_keys, consistency_proof, known_heads, log_origin, \
    newest, writer_key
from authn.audit.proofs import PROOF_FORMAT, prove, verify_proof
from authn.audit.replay import ReplayResult, replay
from authn.audit.signer import checkpoint, rotate_key
from authn.audit.verifier import VerifyReport, verify
from authn.audit.writer import append

__all__ = ["GENESIS", "Entry", "NewEntry", "_iso_db", "batch_entries", "compute_hash", "db_label", "entry_bytes",
           "get_entry", "get_policy", "list_entries", "HeadPlaces", "KnownHead", "accepted_keys", "consistency_proof",
           "known_heads", "log_origin", "newest", "writer_key", "PROOF_FORMAT", "prove", "verify_proof",
           "ReplayResult", "replay", "checkpoint", "rotate_key", "VerifyReport", "verify", "append"]
