"""The audit log: append, verify, tamper detection behind the application's back."""

from __future__ import annotations

from contextlib import contextmanager

import pytest
from sqlalchemy import text
from sqlalchemy.exc import DBAPIError

from authn.audit import Checkpoint, NewEntry, append, checkpoint, list_entries, verify
from registry.db import get_engine
from registry.dbapi import Database


def _fill(url: str, n: int = 6) -> None:
    db = Database(url)
    append(db, [NewEntry("decision", f"S{i}", "accept" if i % 2 else "reject",
                         {"reasons": ["r"], "value": i / 3}) for i in range(n - 1)])
    append(db, [NewEntry("error", None, None, {"error": "truncated file"})])
    db.close()


@contextmanager
def _db(url: str):
    db = Database(url)
    try:
        yield db
    finally:
        db.close()


def _drop_triggers(url: str) -> None:
    engine = get_engine(url)
    with engine.begin() as conn:
        if engine.dialect.name == "sqlite":
            names = [r[0] for r in conn.exec_driver_sql(
                "SELECT name FROM sqlite_master WHERE type='trigger' AND tbl_name='audit_log'")]
            for name in names:
                conn.exec_driver_sql(f"DROP TRIGGER {name}")
        else:
            names = [r[0] for r in conn.exec_driver_sql(
                "SELECT tgname FROM pg_trigger WHERE tgrelid = 'audit_log'::regclass AND NOT tgisinternal")]
            for name in names:
                conn.exec_driver_sql(f"DROP TRIGGER {name} ON audit_log")
    assert names, "the migration must install append-only triggers"


def test_append_and_verify(db_url: str) -> None:
    _fill(db_url)
    with _db(db_url) as s:
        report = verify(s)
        entries = list_entries(s)
    assert report.ok and report.size == 6
    assert [e.seq for e in entries] == list(range(1, 7))
    assert entries[0].prev_hash == "0" * 64
    assert all(b.prev_hash == a.entry_hash for a, b in zip(entries, entries[1:]))
    assert report.head == entries[-1].entry_hash


@pytest.mark.parametrize("statement", ["UPDATE audit_log SET decision = 'accept' WHERE seq = 2",
                                       "DELETE FROM audit_log WHERE seq = 6"])
def test_database_refuses_update_and_delete(db_url: str, statement: str) -> None:
    _fill(db_url)
    with pytest.raises(DBAPIError, match="append-only"):
        with get_engine(db_url).begin() as conn:
            conn.execute(text(statement))
    with _db(db_url) as s:
        assert verify(s).ok and verify(s).size == 6


TAMPERS = {
    "edit payload": ("UPDATE audit_log SET payload = '{\"reasons\":[\"x\"]}' WHERE seq = 3", 3, "modified"),
    "edit decision": ("UPDATE audit_log SET decision = 'reject' WHERE seq = 2", 2, "modified"),
    "delete middle": ("DELETE FROM audit_log WHERE seq = 4", 4, "missing"),
    "reorder": ("UPDATE audit_log SET seq = -2 WHERE seq = 2; UPDATE audit_log SET seq = 2 WHERE seq = 3; "
                "UPDATE audit_log SET seq = 3 WHERE seq = -2", 2, "does not link"),
}


@pytest.mark.parametrize("name", list(TAMPERS))
def test_tampering_is_reported(db_url: str, name: str) -> None:
    statement, bad_seq, word = TAMPERS[name]
    _fill(db_url)
    _drop_triggers(db_url)
    engine = get_engine(db_url)
    with engine.begin() as conn:
        for part in statement.split("; "):
            conn.exec_driver_sql(part)
    with _db(db_url) as s:
        report = verify(s)
    assert not report.ok and report.first_bad_seq == bad_seq and word in report.problem


def test_checkpoint_detects_truncation_and_rewrite(db_url: str) -> None:
    _fill(db_url)
    with _db(db_url) as s:
        cp = checkpoint(s)
    assert cp.size == 6
    _drop_triggers(db_url)
    with get_engine(db_url).begin() as conn:
        conn.exec_driver_sql("DELETE FROM audit_log WHERE seq >= 5")
    with _db(db_url) as s:
        assert verify(s).ok  # a clean truncation keeps a valid chain ...
        report = verify(s, cp)  # ... which only the checkpoint reveals
    assert not report.ok and "truncated" in report.problem
    # rewrite: wipe everything and append a fresh, internally valid history of the same size
    with get_engine(db_url).begin() as conn:
        conn.exec_driver_sql("DELETE FROM audit_log")
    _fill(db_url)
    with _db(db_url) as s:
        assert verify(s).ok
        report = verify(s, cp)
    assert not report.ok and "differs from the checkpoint" in report.problem
    assert Checkpoint.from_json(cp.to_json()) == cp
