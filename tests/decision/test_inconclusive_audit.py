"""Revision 0006: the audit log takes `inconclusive` decisions; a log written before keeps its entries,
its chain and its append-only triggers, and the revision can be taken back while none is inconclusive
(revision 0008 cannot, once the writer has stored leaf bytes)."""

from __future__ import annotations

import hashlib
from datetime import datetime, timezone
from pathlib import Path

import pytest
from sqlalchemy import text

from authn.audit import NewEntry, append, list_entries, verify
from registry.db import alembic_config, create_db_engine, dispose_engines
from registry.dbapi import Database


@pytest.fixture(autouse=True)
def _env(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("AUTHN_LOG_KEY", str(tmp_path / "keys" / "log.pem"))
    monkeypatch.setenv("AUTHN_AUDIT_STH_LOG", str(tmp_path / "keys" / "sth.jsonl"))


def _raw_inconclusive(engine) -> None:
    """One row with decision 'inconclusive', written past the writer (what the CHECK must judge)."""
    with engine.begin() as conn:
        conn.execute(text("INSERT INTO audit_log (seq, created_at, kind, serial, decision, payload, prev_hash, "
                          "entry_hash) VALUES (999, :c, 'decision', 'S', 'inconclusive', '{}', :p, :e)"),
                     {"c": datetime(2026, 1, 1, tzinfo=timezone.utc).replace(tzinfo=None), "p": "0" * 64,
                      "e": "f" * 64})


def _seed_at_0007(engine) -> str:
    """Two entries written as revisions 0001-0007 wrote them (their version 0 leaf bytes are not
    stored; revision 0008 backfills them); returns their tree root."""
    from authn.audit import leaf, merkle

    t0 = datetime(2026, 1, 2, 3, 4, 5, 678901, tzinfo=timezone.utc)
    prev, leaves = "0" * 64, []
    with engine.begin() as conn:
        for seq, (serial, decision) in enumerate((("S1", "accept"), ("S2", "reject")), start=1):
            payload = '{"reasons":["r"]}'
            body = leaf.encode_v0(seq, t0.isoformat(timespec="microseconds"), "decision", serial, decision, payload,
                                  prev)
            stored = t0.replace(tzinfo=None).strftime("%Y-%m-%d %H:%M:%S.%f") \
                if engine.dialect.name == "sqlite" else t0
            digest = hashlib.sha256(body).hexdigest()
            conn.execute(text("INSERT INTO audit_log (seq, created_at, kind, serial, decision, payload, prev_hash, "
                              "entry_hash, leaf_hash) VALUES (:s, :c, 'decision', :se, :d, :p, :pr, :e, :l)"),
                         {"s": seq, "c": stored, "se": serial, "d": decision, "p": payload, "pr": prev, "e": digest,
                          "l": merkle.leaf_hash(body).hex()})
            leaves.append(merkle.leaf_hash(body))
            prev = digest
    return merkle.root_hash(leaves).hex()


def test_revision_0006_takes_inconclusive_and_keeps_the_log(db_url: str) -> None:
    from alembic import command

    from authn.audit import recover

    engine = create_db_engine(db_url)
    with engine.begin() as conn:
        command.upgrade(alembic_config(conn), "0007")
    root = _seed_at_0007(engine)
    with engine.begin() as conn:  # back to 0005: the table rebuilt with the old CHECK, rows and triggers kept
        command.downgrade(alembic_config(conn), "0005")
    with pytest.raises(Exception, match="(?i)check|constraint|too long"):
        _raw_inconclusive(engine)
    engine.dispose()
    dispose_engines()

    db = Database(db_url)  # not at head: migrates to 0006 and on again
    assert verify(db).ok and [e.decision for e in list_entries(db)] == ["accept", "reject"]
    recover(db, root)  # entries from before signing: the operator signs them as they stand
    append(db, [NewEntry("decision", "S3", "inconclusive", {"reasons": ["radar-inconclusive"]})])
    report = verify(db)
    assert report.ok and report.size == 4
    assert [e.serial for e in list_entries(db, decision="inconclusive")] == ["S3"]
    for stmt in ("UPDATE audit_log SET decision = 'accept' WHERE seq = 3", "DELETE FROM audit_log WHERE seq = 1"):
        with pytest.raises(Exception, match="append-only"):
            with db.write():
                db.execute(stmt)
    db.close()
    dispose_engines()
    engine = create_db_engine(db_url)
    with pytest.raises(Exception, match="version 1"):  # entries with stored leaf bytes pin revision 0008
        with engine.begin() as conn:
            command.downgrade(alembic_config(conn), "0005")
    engine.dispose()
