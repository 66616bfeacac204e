"""Revision 0002 keeps every entry written at revision 0001 and makes them the tree's first leaves; no signed
head vouches for them, so appends wait for `authn audit recover` to sign them as they stand."""

from __future__ import annotations

import hashlib
import json
import subprocess
import sys
from datetime import datetime, timedelta, timezone
from pathlib import Path

import pytest
from sqlalchemy import text

from authn.audit import merkle
from authn.audit import NewEntry, append, export, known_heads, list_entries, prove, recover, verify, verify_proof
from authn.audit.logkey import LogKey
from core.errors import SystemFault
from registry.db import alembic_config, create_db_engine, dispose_engines
from registry.dbapi import Database


@pytest.fixture(autouse=True)
def _env(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("AUTHN_LOG_KEY", str(tmp_path / "keys" / "log.pem"))
    monkeypatch.setenv("AUTHN_AUDIT_STH_LOG", str(tmp_path / "keys" / "sth.jsonl"))


def _old_body(seq, created: datetime, kind, serial, decision, payload, prev) -> bytes:
    """Revision 0001's chain input, written out here so that this test does not use today's code."""
    return json.dumps({"seq": seq, "created_at": created.isoformat(timespec="microseconds"), "kind": kind,
                       "serial": serial, "decision": decision, "payload": payload, "prev_hash": prev},
                      sort_keys=True, separators=(",", ":"), ensure_ascii=False).encode()


def test_upgrade_from_0001_keeps_entries_as_leaves(db_url: str, tmp_path: Path) -> None:
    from alembic import command

    engine = create_db_engine(db_url)
    with engine.begin() as conn:
        command.upgrade(alembic_config(conn), "0001")
    t0 = datetime(2026, 1, 2, 3, 4, 5, 678901, tzinfo=timezone.utc)
    prev, bodies = "0" * 64, []
    with engine.begin() as conn:
        for seq in range(1, 8):
            created = t0 + timedelta(seconds=seq)
            kind, decision = ("error", None) if seq == 4 else ("decision", "accept" if seq % 2 else "reject")
            payload = json.dumps({"reasons": ["r"], "n": seq}, sort_keys=True, separators=(",", ":"))
            body = _old_body(seq, created, kind, f"S{seq}", decision, payload, prev)
            digest = hashlib.sha256(body).hexdigest()
            stored = created.replace(tzinfo=None) if engine.dialect.name == "sqlite" else created
            if engine.dialect.name == "sqlite":
                stored = stored.strftime("%Y-%m-%d %H:%M:%S.%f")
            conn.execute(text("INSERT INTO audit_log (seq, created_at, kind, serial, decision, payload, prev_hash, "
                              "entry_hash) VALUES (:s, :c, :k, :se, :d, :p, :pr, :e)"),
                         {"s": seq, "c": stored, "k": kind, "se": f"S{seq}", "d": decision, "p": payload,
                          "pr": prev, "e": digest})
            bodies.append(body)
            prev = digest
    engine.dispose()
    dispose_engines()

    db = Database(db_url)  # not at head: migrates
    entries = list_entries(db)
    assert [e.leaf_hash for e in entries] == [merkle.leaf_hash(b).hex() for b in bodies]
    stored = [bytes(b) for (b,) in db.fetch("SELECT leaf_bytes FROM audit_log ORDER BY seq")]
    assert stored == bodies  # revision 0008 keeps the bytes the hashes were computed over
    assert verify(db).ok  # a whole chain, which no signed head vouches for yet:
    with pytest.raises(SystemFault, match="key .* is missing but the log has entries"):
        append(db, [NewEntry("decision", "NEW", "accept", {"reasons": []})])
    old_root = merkle.root_hash([merkle.leaf_hash(b) for b in bodies]).hex()
    assert recover(db, old_root).seq == 8  # the operator signs the entries as they stand
    append(db, [NewEntry("decision", "NEW", "accept", {"reasons": []})])
    report = verify(db, known_heads(db), public_key=LogKey.load().public_key, require_signed_to_end=True)
    assert report.ok and report.size == 9
    assert report.root == merkle.root_hash([merkle.leaf_hash(b) for b in bodies] + [
        bytes.fromhex(e.leaf_hash) for e in list_entries(db)[-2:]]).hex()
    doc = prove(db, 2)
    assert verify_proof(doc, LogKey.load().public_key).startswith("ok")
    legacy = {k: v for k, v in doc.items() if k != "leaf_bytes"} | {"format": "authn-inclusion-proof/1"}
    assert verify_proof(legacy, LogKey.load().public_key).startswith("ok")  # a proof issued before 0008
    export(db, tmp_path / "export")  # version 0 and version 1 leaves in one export
    done = subprocess.run([sys.executable, str(Path(__file__).resolve().parents[2] / "tools" /
                                               "verify_audit_export.py"), str(tmp_path / "export")],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 0 and done.stdout.startswith("OK: 9 entries"), done.stderr
    for stmt in ("UPDATE audit_log SET decision = 'accept' WHERE seq = 2", "DELETE FROM audit_log WHERE seq = 1"):
        with pytest.raises(Exception, match="append-only"):
            with db.write():
                db.execute(stmt)
    db.close()
