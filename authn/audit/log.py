"""`AuditLog`: the one way the product records into the audit log.

A check records its decisions and failed attempts, `authn serve` its registry changes; each
through this class, so the entry kinds and the error payload are built in one place and
every append goes through the writer's proof (authn.audit.writer)."""

from __future__ import annotations

import sys
import threading
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

from authn.audit.entries import Entry, NewEntry
from authn.audit.writer import append
from core.errors import EXIT_BAD_INPUT
from registry.dbapi import Database

#: What signing the log's head imports (`core.pem` loads the log key with them): ~12 ms cold
SIGNING_MODULES = ("cryptography.hazmat.primitives.serialization", "cryptography.hazmat.primitives.asymmetric.ed25519")
#: RFC 8410's example Ed25519 private key: parsed and used once to sign, so that OpenSSL's
#: first-use set-up of its PEM decoder and of Ed25519 (~1.5 ms) is paid before the audit
_EXAMPLE_KEY = (b"-----BEGIN PRIVATE KEY-----\nMC4CAQAwBQYDK2VwBCIEINTuctv5E1hK1bbY8fdp+K06/nwoy/HU++CXqI9EdVhC\n"
                b"-----END PRIVATE KEY-----\n")


def _prepare_signing() -> None:
    import importlib

    try:
        from core.pem import private_key

        for name in SIGNING_MODULES:
            importlib.import_module(name)
        private_key(_EXAMPLE_KEY).sign(b"")
    except Exception:  # noqa: BLE001 - the append imports and loads again, and fails closed there
        pass


@contextmanager
def signing_warmed() -> Iterator[None]:
    """Import `SIGNING_MODULES` and sign once with `_EXAMPLE_KEY` in a background thread while
    the body runs, and wait for it at the end: a cold check's radar stages hide the import and
    set-up that its audit stage would otherwise pay. The body must import none of them itself
    (the radar does not), so no two threads import the same package at once; a failure there is
    left for the append to meet again, and fail closed on."""
    if all(name in sys.modules for name in SIGNING_MODULES):
        yield
        return
    worker = threading.Thread(target=_prepare_signing, name="authn-signing-warm-up", daemon=True)
    worker.start()
    try:
        yield
    finally:
        worker.join()


@dataclass(frozen=True)
class AuditLog:
    """The audit log of one database; `policy_text`, when given, is recorded with every
    append and its SHA-256 put in each entry's payload (see `append`)."""

    db: Database
    policy_text: str | None = None

    @staticmethod
    def decision(serial: str | None, decision: str, payload: dict[str, Any]) -> NewEntry:
        """A decision entry: `payload` is the outcome's audit payload."""
        return NewEntry("decision", serial, decision, payload)

    @staticmethod
    def error(file: str, serial: str | None, error: str, exit_code: int, *, policy_sha256: str | None,
              track_files: Sequence[str] | None = None) -> NewEntry:
        """The entry of a check that ended without a decision: the file, the one-line error, its
        kind (`bad-input` for exit 2, else `system`), and a track's files when it was one."""
        payload: dict[str, Any] = {"file": file, "error": error,
                                   "error_kind": "bad-input" if exit_code == EXIT_BAD_INPUT else "system",
                                   "policy_sha256": policy_sha256}
        if track_files is not None:
            payload["track_files"] = list(track_files)
        return NewEntry("error", serial, None, payload)

    def record(self, entries: Sequence[NewEntry], *, idempotency_key: str | None = None) -> list[Entry]:
        """Append `entries` in one transaction (see authn.audit.writer.append); raises if it
        does not commit, so the caller prints nothing it did not record."""
        return append(self.db, entries, policy_text=self.policy_text, idempotency_key=idempotency_key)

    def record_decision(self, serial: str | None, decision: str, payload: dict[str, Any]) -> Entry:
        return self.record([self.decision(serial, decision, payload)])[0]

    def record_registry_change(self, serial: str, action: str, api_key_id: int, role: str,
                               detail: dict[str, Any]) -> Entry:
        """A registry change through `authn serve`, naming the acting API key and its role."""
        payload = {"action": action, "api_key_id": api_key_id, "role": role, **detail}
        return self.record([NewEntry("registry", serial, None, payload)])[0]
