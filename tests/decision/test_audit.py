"""The audit log: append, verify, policies, proofs, replay, the CLI's exit codes."""

from __future__ import annotations

import json
import os
from contextlib import contextmanager
from pathlib import Path

import pytest
from sqlalchemy import text
from sqlalchemy.exc import DBAPIError

from authn.audit import (NewEntry, append, checkpoint, get_policy, known_heads, list_entries, prove, verify,
                         verify_proof)
from authn.cli import main
from core.errors import AuthnError, SystemFault
from authn.audit.logkey import LogKey
from authn.audit.tree_head import SignedTreeHead
from registry.db import get_engine
from registry.dbapi import Database

POLICY = "@id(\"all\") permit(principal, action, resource);"


@pytest.fixture(autouse=True)
def _log_key(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A log key and STH file per test, never the user's."""
    monkeypatch.setenv("AUTHN_LOG_KEY", str(tmp_path / "keys" / "log.pem"))
    monkeypatch.setenv("AUTHN_AUDIT_STH_LOG", str(tmp_path / "keys" / "sth.jsonl"))
    return tmp_path / "keys" / "log.pem"


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


def _drop_triggers(url: str, table: str = "audit_log") -> None:
    engine = get_engine(url)
    with engine.begin() as conn:
        if engine.dialect.name == "sqlite":
            names = [r[0] for r in conn.exec_driver_sql(
                f"SELECT name FROM sqlite_master WHERE type='trigger' AND tbl_name='{table}'")]
            for name in names:
                conn.exec_driver_sql(f"DROP TRIGGER {name}")
        else:
            names = [r[0] for r in conn.exec_driver_sql(
                f"SELECT tgname FROM pg_trigger WHERE tgrelid = '{table}'::regclass AND NOT tgisinternal")]
            for name in names:
                conn.exec_driver_sql(f"DROP TRIGGER {name} ON {table}")
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
    assert all(e.leaf_hash and len(e.leaf_hash) == 64 for e in entries)


@pytest.mark.parametrize("statement", ["UPDATE audit_log SET decision = 'accept' WHERE seq = 2",
                                       "DELETE FROM audit_log WHERE seq = 6",
                                       "DELETE FROM audit_tree_heads",
                                       "UPDATE audit_tree_heads SET tree_size = 1",
                                       "DELETE FROM audit_policies"])
def test_database_refuses_update_and_delete(db_url: str, statement: str) -> None:
    _fill(db_url)
    with _db(db_url) as s:
        append(s, [NewEntry("decision", "P", "accept", {"reasons": []})], policy_text=POLICY)
    with pytest.raises(DBAPIError, match="append-only"):
        with get_engine(db_url).begin() as conn:
            conn.execute(text(statement))
    with _db(db_url) as s:
        assert verify(s).ok and verify(s).size == 7


def test_first_append_signs_a_head_inside_and_outside_the_database(db_url: str, _log_key: Path) -> None:
    _fill(db_url)
    with _db(db_url) as s:
        heads = known_heads(s)
    periodic = [h for h in heads if "-latest-" not in h.source]
    latest = [h for h in heads if "-latest-" in h.source]
    assert [(h.source.split()[0], h.sth.tree_size) for h in periodic] == [("file", 5), ("database", 5),
                                                                          ("database", 6)]
    assert [h.sth.tree_size for h in latest] == [6]  # every commit signs the head of the whole log
    assert oct(_log_key.stat().st_mode & 0o777) == "0o600"


def test_automatic_checkpoints_every_k(db_url: str, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("AUTHN_AUDIT_CHECKPOINT_EVERY", "10")
    with _db(db_url) as s:
        for i in range(35):
            append(s, [NewEntry("decision", f"S{i}", "accept", {"reasons": []})])
        sizes = sorted({h.sth.tree_size for h in known_heads(s)})
        key = LogKey.load()
        report = verify(s, known_heads(s), public_key=key.public_key)
    assert sizes == [1, 11, 21, 31, 35]  # every 10 entries, and the latest head (every commit)
    assert report.ok and report.unsigned == 0 and len(report.checked) == 10


def test_policy_recorded_once_and_added_to_error_entries(db_url: str) -> None:
    with _db(db_url) as s:
        append(s, [NewEntry("error", "S", None, {"error": "bad file"})], policy_text=POLICY)
        append(s, [NewEntry("decision", "S", "accept", {"reasons": []})], policy_text=POLICY)
        entries = list_entries(s, kind="error")
        assert get_policy(s, entries[0].payload["policy_sha256"]) == POLICY
        assert s.fetch("SELECT COUNT(*) FROM audit_policies")[0][0] == 1
    assert len(entries) == 1


def _decision_payload(serial: str) -> dict:
    principal = {"registered": False, "status": "unregistered", "model": "", "id_type": "", "valid_from_s": 0}
    return {"reasons": ["all"], "policy_input": {"serial": serial, "principal": principal, "resource": {},
                                                  "context": {}}}


def test_replay(db_url: str) -> None:
    from authn.policy import PolicyEngine

    engine = PolicyEngine.load()
    with _db(db_url) as s:
        append(s, [NewEntry("decision", "S", "accept", {"reasons": ["r"]})])  # no policy_input: old entry
        append(s, [NewEntry("error", "S", None, {"error": "x"})], policy_text=engine.text)
        assert main(["--db", db_url, "audit", "replay", "1"]) == 2
        assert main(["--db", db_url, "audit", "replay", "2"]) == 2
        assert main(["--db", db_url, "audit", "replay", "99"]) == 2


def test_checkpoint_detects_truncation_and_rewrite(db_url: str) -> None:
    _fill(db_url)
    with _db(db_url) as s:
        cp = checkpoint(s)
        key = LogKey.load()
    assert cp.tree_size == 6
    _drop_triggers(db_url)
    with get_engine(db_url).begin() as conn:
        conn.exec_driver_sql("DELETE FROM audit_log WHERE seq >= 5")
    with _db(db_url) as s:
        assert verify(s).ok  # a clean truncation keeps a valid chain ...
        report = verify(s, cp, public_key=key.public_key)  # ... which only the signed head reveals
    assert not report.ok and "truncated" in report.problem
    with get_engine(db_url).begin() as conn:
        conn.exec_driver_sql("DELETE FROM audit_log")
    with pytest.raises(SystemFault, match="truncated"):
        _fill(db_url)  # the log refuses to grow over a truncated history
    with pytest.raises(SystemFault, match="truncated"):
        for latest in Path(os.environ["AUTHN_AUDIT_STH_LOG"]).parent.glob("*-latest-*.json"):
            latest.unlink()  # the latest-head file deleted: the STH log still holds the periodic head
        _fill(db_url)
    Path(os.environ["AUTHN_AUDIT_STH_LOG"]).unlink()  # an intruder who can also delete the STH log ...
    _drop_triggers(db_url, "audit_tree_heads")
    with get_engine(db_url).begin() as conn:
        conn.exec_driver_sql("DELETE FROM audit_tree_heads")  # ... and the heads in the database
    with pytest.raises(SystemFault, match="no signed head vouches"):
        _fill(db_url)  # ... still cannot start the log again: it has an origin
    _drop_triggers(db_url, "audit_log_meta")
    with get_engine(db_url).begin() as conn:
        conn.exec_driver_sql("DELETE FROM audit_log_meta")  # and with the origin gone too ...
    _fill(db_url)
    with _db(db_url) as s:
        assert verify(s).ok
        report = verify(s, cp, public_key=key.public_key)  # ... is still caught by a head kept elsewhere
    assert not report.ok and "names the log" in report.problem  # (the new log has a new origin)
    assert SignedTreeHead.from_json(cp.to_json()) == cp


def test_cli_checkpoint_prove_verify_proof(db_url: str, tmp_path: Path, capsys) -> None:
    _fill(db_url)
    sth, pub, proof = tmp_path / "sth.json", tmp_path / "pub.pem", tmp_path / "p.json"
    assert main(["--db", db_url, "audit", "checkpoint", "--out", str(sth)]) == 0
    assert main(["--db", db_url, "audit", "public-key", "--out", str(pub)]) == 0
    assert main(["--db", db_url, "audit", "verify", "--against", str(sth)]) == 0
    assert main(["--db", db_url, "audit", "prove", "4", "--out", str(proof)]) == 0
    capsys.readouterr()
    assert main(["audit", "verify-proof", str(proof), "--public-key", str(pub)]) == 0
    assert "entry 4 is leaf 3" in capsys.readouterr().out
    # binary / wrong STH files: one line, exit 2
    bad = tmp_path / "bad.bin"
    bad.write_bytes(b"\x89PNG\xff\xfe\x00")
    for f in (bad, tmp_path / "missing.json", pub):
        assert main(["--db", db_url, "audit", "verify", "--against", str(f)]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "Traceback" not in err
    assert main(["--db", db_url, "audit", "list", "--decision", "error", "--json"]) == 0
    assert [e["kind"] for e in json.loads(capsys.readouterr().out)] == ["error"]


def test_missing_log_key_is_a_system_fault(db_url: str, tmp_path: Path, capsys) -> None:
    _fill(db_url)
    assert main(["--db", db_url, "audit", "verify", "--log-key", str(tmp_path / "nope.pem")]) == 3
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "does not exist" in err
    corrupt = tmp_path / "corrupt.pem"
    corrupt.write_text("not a key")
    assert main(["--db", db_url, "audit", "verify", "--log-key", str(corrupt)]) == 3


PROOF_FIELDS = [("entry", "serial", "S9"), ("entry", "decision", "maybe"), ("entry", "payload", "{}"),
                ("entry", "created_at", "2020-01-01T00:00:00.000000+00:00"), ("entry", "seq", 2),
                ("entry", "prev_hash", "1" * 64), ("entry", "kind", "error"), ("entry", "entry_hash", "2" * 64),
                (None, "leaf_index", 0), (None, "tree_size", 4), (None, "leaf_bytes", "AXt9"),
                ("sth", "tree_size", 7), ("sth", "timestamp", 1), ("sth", "root_hash", "3" * 64),
                ("sth", "log_key_id", "4" * 64)]


def test_inclusion_proof_fails_for_any_altered_field(db_url: str) -> None:
    _fill(db_url)
    with _db(db_url) as s:
        doc = prove(s, 3)
    key = LogKey.load().public_key
    assert verify_proof(doc, key).startswith("ok")
    for where, name, value in PROOF_FIELDS:
        bad = json.loads(json.dumps(doc))
        target = bad if where is None else bad[where]
        assert target[name] != value
        target[name] = value
        with pytest.raises(AuthnError):
            verify_proof(bad, key)
    for i in range(len(doc["audit_path"])):
        bad = json.loads(json.dumps(doc))
        bad["audit_path"][i] = "5" * 64
        with pytest.raises(AuthnError):
            verify_proof(bad, key)
    other = LogKey.load(Path(LogKey.load().path).with_name("other.pem"), create=True).public_key
    with pytest.raises(AuthnError, match="not signed"):
        verify_proof(doc, other)


def test_newest_sth_line_read_backwards_matches_a_full_read(tmp_path: Path) -> None:
    """The writer reads the STH log from its end in 64 KiB blocks: whatever the lines' sizes
    and owners, it finds the same newest line as reading every line."""
    import random

    from authn.audit.head_files import append_sth_log, newest_in_sth_log, read_sth_log
    from authn.audit.logkey import create_key_file

    create_key_file(tmp_path / "k.pem")
    key = LogKey.load(tmp_path / "k.pem")
    rng = random.Random(5)
    path = tmp_path / "sth.jsonl"
    for i in range(900):
        origin = "authn.invalid/" + "x" * rng.randrange(1, 240)  # lines of 0.4-0.9 KiB: many cut by blocks
        append_sth_log(path, key.sign_tree_head(i, bytes(32), i, origin), rng.choice("ABBC"))
        if i % 97 == 0 or i == 899:
            for label in "ABCD":
                full = [sth for owner, sth in read_sth_log(path) if owner == label]
                assert newest_in_sth_log(path, label) == (full[-1] if full else None)
