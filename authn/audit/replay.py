"""`replay`: re-decide an entry with the policy text it was decided under."""

from __future__ import annotations

import hashlib
from dataclasses import dataclass

from authn.audit.entries import get_entry, get_policy
from core.errors import AuthnError, SystemFault
from registry.dbapi import Database

@dataclass(frozen=True)
class ReplayResult:
    seq: int
    same: bool
    recorded: tuple[str | None, list[str]]
    replayed: tuple[str, list[str]]
    policy_sha256: str



def replay(db: Database, seq: int) -> ReplayResult:
    """Re-decide entry `seq` with the policy text it was decided under (from audit_policies)."""
    entry = get_entry(db, seq)
    if entry is None:
        raise AuthnError(f"no audit entry {seq}")
    if entry.kind != "decision":
        raise AuthnError(f"not replayable: entry {seq} is an error entry")
    inputs, sha = entry.payload.get("policy_input"), entry.payload.get("policy_sha256")
    if not isinstance(inputs, dict) or not isinstance(sha, str):
        raise AuthnError(f"not replayable: entry {seq} has no policy_input (written before replay was recorded)")
    try:
        serial, principal = inputs["serial"], inputs["principal"]
        resource, context = inputs["resource"], inputs["context"]
    except KeyError as exc:
        raise AuthnError(f"not replayable: entry {seq}'s policy_input has no {exc.args[0]!r}") from None
    text = get_policy(db, sha)
    if text is None:
        raise AuthnError(f"not replayable: policy {sha[:16]} of entry {seq} is not recorded in the log")
    if hashlib.sha256(text.encode()).hexdigest() != sha:
        raise SystemFault(f"recorded policy {sha[:16]} does not hash to its SHA-256 (audit_policies altered)")
    from authn.policy import PolicyEngine

    result = PolicyEngine.from_text(text, f"policy {sha[:16]}").decide(serial, principal, resource, context)
    recorded = (entry.decision, list(entry.payload.get("reasons", [])))
    replayed = (result.decision, list(result.reasons))
    return ReplayResult(seq, recorded == replayed, recorded, replayed, sha)
