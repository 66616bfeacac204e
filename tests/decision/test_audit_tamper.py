"""Tampering by someone who can write the database (a DBA dropping the append-only triggers).

Each tamper is done once to entries the last periodic signed tree head (STH) covers
("before" the last checkpoint) and once to entries after it; `verify` is given the latest
signed tree head -- the one every append signs over the whole log and keeps outside the
database -- and must report every case. Appending to a tampered log is refused.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import pytest

from authn import merkle
from authn.audit import NewEntry, append, checkpoint, entry_bytes, verify
from authn.errors import SystemFault
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


# name: (tamper, entry "before" (covered by the periodic STH), entry "after" it)
TAMPERS = {
    "edit an entry": (_edit, 3, 8),
    "delete a middle entry": (_delete, 3, 8),
    "delete the tail": (_delete_tail, 5, 9),
    "truncate all": (_truncate, 1, 1),
    "reorder two entries": (_reorder, 3, 8),
    "forged entry, chain recomputed": (_forge_insert, 3, 11),
    "rewrite and recompute the whole chain": (_rewrite_recompute, 2, 8),
    "reorder, chain recomputed": (_reorder_recompute, 2, 8),
    "delete, chain recomputed": (_delete_recompute, 2, 9),
}
CASES = [(name, where) for name in TAMPERS for where in ("before", "after")]


def _latest_head(url: str):
    """The latest signed tree head, as kept outside the database (what a verifier holds)."""
    from authn.audit import db_label
    from authn.logkey import latest_head_path, read_latest_head, sth_log_path

    db = Database(url)
    try:
        return read_latest_head(latest_head_path(sth_log_path(), db_label(db)))
    finally:
        db.close()


@pytest.mark.parametrize("name,where", CASES, ids=[f"{n}-{w}" for n, w in CASES])
def test_tamper_is_detected(db_url: str, name: str, where: str) -> None:
    tamper, before, after = TAMPERS[name]
    periodic, key = _setup(db_url)
    latest = _latest_head(db_url)
    assert latest.tree_size == SIGNED + 4 > periodic.tree_size
    with get_engine(db_url).begin() as conn:
        tamper(conn, before if where == "before" else after)
    db = Database(db_url)
    report = verify(db, [periodic, latest], public_key=key, require_signed_to_end=True)
    db.close()
    assert not report.ok, name
    assert report.first_bad_seq is not None and report.problem


GROWING_OVER = {"delete the tail": (_delete_tail, 9), "truncate all": (_truncate, 1),
                "forged append": (_forge_insert, 11), "rewrite after the checkpoint": (_rewrite_recompute, 8)}


@pytest.mark.parametrize("name", list(GROWING_OVER))
def test_append_refuses_to_grow_a_tampered_log(db_url: str, name: str) -> None:
    """The next decision is not appended over a truncated, extended or rewritten history
    (the writer checks the stored leaves against its latest signed head; content edits that
    keep the stored leaf hashes are verify's to find, above)."""
    tamper, where = GROWING_OVER[name]
    _setup(db_url)
    with get_engine(db_url).begin() as conn:
        tamper(conn, where)
    db = Database(db_url)
    try:
        with pytest.raises(SystemFault, match="audit log"):
            append(db, [NewEntry("decision", "NEXT", "reject", {"reasons": ["r"]})])
    finally:
        db.close()


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
