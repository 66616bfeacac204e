"""Tampering by someone who can write the database (a DBA dropping the append-only triggers).

Each tamper is done once to entries a signed tree head (STH) covers ("before" the last
checkpoint) and once to entries after it; `verify` is given that latest STH. Entries no
STH covers yet are protected by the unkeyed chain only: a tamper that recomputes the
chain there (forged append, tail deletion, rewrite) cannot be told from honest history,
which `test_unsigned_tail_is_only_chain_protected` pins down (the window is K entries /
T seconds, see authn.audit).
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import pytest

from authn import merkle
from authn.audit import NewEntry, append, checkpoint, entry_bytes, verify
from authn.logkey import LogKey
from registry.db import get_engine
from registry.dbapi import Database

SIGNED = 6  # the STH covers entries 1..6; 7..10 come after it


@pytest.fixture(autouse=True)
def _env(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("AUTHN_LOG_KEY", str(tmp_path / "keys" / "log.pem"))
    monkeypatch.setenv("AUTHN_AUDIT_STH_LOG", str(tmp_path / "keys" / "sth.jsonl"))
    monkeypatch.setenv("AUTHN_AUDIT_CHECKPOINT_EVERY", "1000000")
    monkeypatch.setenv("AUTHN_AUDIT_CHECKPOINT_SECONDS", "1000000")


def _setup(url: str):
    db = Database(url)
    append(db, [NewEntry("decision", f"S{i}", "accept" if i % 2 else "reject", {"reasons": ["r"], "i": i})
                for i in range(SIGNED)])
    sth = checkpoint(db)
    append(db, [NewEntry("decision", f"T{i}", "reject", {"reasons": ["r"], "i": i}) for i in range(4)])
    db.close()
    engine = get_engine(url)
    with engine.begin() as conn:  # what a DBA would do
        if engine.dialect.name == "sqlite":
            for (name,) in conn.exec_driver_sql("SELECT name FROM sqlite_master WHERE type='trigger'").all():
                conn.exec_driver_sql(f"DROP TRIGGER {name}")
        else:
            for table in ("audit_log", "audit_tree_heads", "audit_policies"):
                conn.exec_driver_sql(f"ALTER TABLE {table} DISABLE TRIGGER ALL")
    return sth, LogKey.load().public_key


def _rows(conn) -> list[list]:
    return [list(r) for r in conn.exec_driver_sql(
        "SELECT seq, created_at, kind, serial, decision, payload FROM audit_log ORDER BY seq").all()]


def _iso(v) -> str:
    from authn.audit import _iso_db

    return _iso_db(v)


def _rewrite(conn, rows: list[list]) -> None:
    """Replace the whole log by `rows`, recomputing chain and leaf hashes (a careful forger)."""
    conn.exec_driver_sql("DELETE FROM audit_log")
    prev = "0" * 64
    for i, (_, created, kind, serial, decision, payload) in enumerate(rows, start=1):
        body = entry_bytes(i, _iso(created), kind, serial, decision, payload, prev)
        digest = hashlib.sha256(body).hexdigest()
        conn.exec_driver_sql(
            "INSERT INTO audit_log (seq, created_at, kind, serial, decision, payload, prev_hash, entry_hash, "
            "leaf_hash) VALUES (%s)" % ", ".join(["?"] * 9) if conn.dialect.name == "sqlite" else
            "INSERT INTO audit_log (seq, created_at, kind, serial, decision, payload, prev_hash, entry_hash, "
            "leaf_hash) VALUES (%s)" % ", ".join(["%s"] * 9),
            (i, created, kind, serial, decision, payload, prev, digest, merkle.leaf_hash(body).hex()))
        prev = digest


def _edit(conn, k):
    conn.exec_driver_sql(f"UPDATE audit_log SET payload = '{{\"reasons\":[\"x\"]}}' WHERE seq = {k}")


def _delete(conn, k):
    conn.exec_driver_sql(f"DELETE FROM audit_log WHERE seq = {k}")


def _delete_tail(conn, k):
    conn.exec_driver_sql(f"DELETE FROM audit_log WHERE seq >= {k}")


def _truncate(conn, k):
    conn.exec_driver_sql("DELETE FROM audit_log")


def _reorder(conn, k):
    conn.exec_driver_sql(f"UPDATE audit_log SET seq = -1 WHERE seq = {k}")
    conn.exec_driver_sql(f"UPDATE audit_log SET seq = {k} WHERE seq = {k + 1}")
    conn.exec_driver_sql(f"UPDATE audit_log SET seq = {k + 1} WHERE seq = -1")


def _forge_insert(conn, k):
    """A forged entry at position k with the chain recomputed from there (an append, for k = end + 1)."""
    rows = _rows(conn)
    forged = [0, rows[0][1], "decision", "EVIL", "accept", json.dumps({"reasons": ["forged"]})]
    _rewrite(conn, rows[:k - 1] + [forged] + rows[k - 1:])


def _rewrite_recompute(conn, k):
    rows = _rows(conn)
    rows[k - 1][4] = "accept" if rows[k - 1][4] == "reject" else "reject"
    _rewrite(conn, rows)


def _reorder_recompute(conn, k):
    rows = _rows(conn)
    rows[k - 1], rows[k] = rows[k], rows[k - 1]
    _rewrite(conn, rows)


def _delete_recompute(conn, k):
    rows = _rows(conn)
    del rows[k - 1]
    _rewrite(conn, rows)


# name: (tamper, entry "before" (covered by the STH), entry "after" or None when undetectable there)
TAMPERS = {
    "edit an entry": (_edit, 3, 8),
    "delete a middle entry": (_delete, 3, 8),
    "delete the tail": (_delete_tail, 5, None),
    "truncate all": (_truncate, 1, 1),
    "reorder two entries": (_reorder, 3, 8),
    "forged entry, chain recomputed": (_forge_insert, 3, None),
    "rewrite and recompute the whole chain": (_rewrite_recompute, 2, None),
    "reorder, chain recomputed": (_reorder_recompute, 2, None),
    "delete, chain recomputed": (_delete_recompute, 2, None),
}
CASES = [(name, where) for name in TAMPERS for where in ("before", "after") if
         TAMPERS[name][1 if where == "before" else 2] is not None]


@pytest.mark.parametrize("name,where", CASES, ids=[f"{n}-{w}" for n, w in CASES])
def test_tamper_is_detected(db_url: str, name: str, where: str) -> None:
    tamper, before, after = TAMPERS[name]
    sth, key = _setup(db_url)
    with get_engine(db_url).begin() as conn:
        tamper(conn, before if where == "before" else after)
    db = Database(db_url)
    report = verify(db, sth, public_key=key)
    db.close()
    assert not report.ok, name
    assert report.first_bad_seq is not None and report.problem


@pytest.mark.parametrize("tamper", [_delete_tail, _forge_insert, _rewrite_recompute],
                         ids=["delete tail", "forged append", "rewrite"])
def test_unsigned_tail_is_only_chain_protected(db_url: str, tamper) -> None:
    """Known limit: after the newest STH, a chain-recomputing forger is not detectable."""
    sth, key = _setup(db_url)
    with get_engine(db_url).begin() as conn:
        tamper(conn, {_delete_tail: 9, _forge_insert: 11, _rewrite_recompute: 8}[tamper])
    db = Database(db_url)
    report = verify(db, sth, public_key=key)
    db.close()
    assert report.ok and report.unsigned > 0  # reported as unsigned, not as broken


def test_forged_tree_head_in_the_database_is_reported(db_url: str, tmp_path: Path, capsys) -> None:
    from authn.cli import main

    sth, _ = _setup(db_url)
    with get_engine(db_url).begin() as conn:
        conn.exec_driver_sql(
            "INSERT INTO audit_tree_heads (tree_size, timestamp_ms, root_hash, log_key_id, signature, frontier) "
            f"VALUES (10, 1, '{'a' * 64}', '{sth.log_key_id}', '{sth.signature}', '[]')")
    assert main(["--db", db_url, "audit", "verify"]) == 1
    assert "not signed by the log key" in capsys.readouterr().err


def test_cli_verify_uses_the_external_sth_file(db_url: str, capsys) -> None:
    """Truncation after deleting the in-database heads too: the STH file outside still knows."""
    from authn.cli import main

    _setup(db_url)
    with get_engine(db_url).begin() as conn:
        conn.exec_driver_sql("DELETE FROM audit_log WHERE seq >= 3")
        conn.exec_driver_sql("DELETE FROM audit_tree_heads")
    assert main(["--db", db_url, "audit", "verify"]) == 1
    err = capsys.readouterr().err
    assert "truncated" in err and "sth.jsonl" in err and err.count("\n") == 1
