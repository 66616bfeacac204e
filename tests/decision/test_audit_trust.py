"""What the log trusts (issue 55): no key or signature over entries no trusted head vouches for,
`authn audit recover` as the one way to sign them, a signed right edge, one stored form per
instant, damaged head sources reported, the first entry that differs named, malformed rows
and deeply nested JSON refused with one line.

Every tamper here is a database writer's (the append-only triggers dropped) or a file
writer's (the key, the STH log, the latest-head file); both are played on SQLite and, with
AUTHN_TEST_POSTGRES_URL, on PostgreSQL.
"""

from __future__ import annotations

import hashlib
import json
import os
from datetime import timedelta, timezone
from pathlib import Path

import pytest

from tests.audit_tools import drop_triggers
from tests.flights import write_m300_flight
from sqlalchemy import text

from authn.audit import NewEntry, append, db_label, leaf, list_entries, merkle
from authn.audit.head_files import latest_head_path, sth_log_path
from authn.cli import main
from core.errors import SystemFault
from registry.db import get_engine
from registry.dbapi import Database


@pytest.fixture(autouse=True)
def _env(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("AUTHN_LOG_KEY", str(tmp_path / "keys" / "log.pem"))
    monkeypatch.setenv("AUTHN_AUDIT_STH_LOG", str(tmp_path / "keys" / "sth.jsonl"))
    monkeypatch.setenv("AUTHN_AUDIT_CHECKPOINT_EVERY", "4")
    monkeypatch.setenv("AUTHN_AUDIT_CHECKPOINT_SECONDS", "1000000")


def _fill(url: str, n: int = 10) -> None:
    """n entries, one append (one signed head) each, as n `authn check` runs make them."""
    db = Database(url)
    for i in range(1, n + 1):
        append(db, [NewEntry("decision", f"S{i}", "accept" if i % 2 else "reject", {"reasons": ["r"], "i": i})])
    db.close()


def _next_append(url: str) -> None:
    db = Database(url)
    try:
        append(db, [NewEntry("decision", "NEXT", "reject", {"reasons": ["r"]})])
    finally:
        db.close()


def _files(url: str) -> tuple[Path, Path, Path]:
    """The key, the STH log and this database's latest-head file."""
    db = Database(url)
    try:
        sth_log = sth_log_path()
        return Path(os.environ["AUTHN_LOG_KEY"]), sth_log, latest_head_path(sth_log, db_label(db))
    finally:
        db.close()


def _verify(url: str, capsys, *extra: str) -> tuple[int, str]:
    capsys.readouterr()
    code = main(["--db", url, "audit", "verify", *extra])
    captured = capsys.readouterr()
    return code, captured.err + captured.out


def _recompute(conn, rows: dict[int, dict], first: int, last: int) -> None:
    """Entries first..last replaced by `rows` (by seq), their chain and leaf hashes recomputed
    from the stored hash of entry first - 1; the entries after them are left as they are."""
    prev = conn.execute(text("SELECT entry_hash FROM audit_log WHERE seq = :s"), {"s": first - 1}).scalar() \
        if first > 1 else "0" * 64
    for seq in range(first, last + 1):
        r = rows[seq]
        when = leaf.time_text(Database.from_db_time(r["created_at"]))
        body = leaf.encode(seq, when, r["kind"], r["serial"], r["decision"], r["payload"], prev)
        digest = hashlib.sha256(body).hexdigest()
        conn.execute(text("UPDATE audit_log SET created_at = :c, kind = :k, serial = :s, decision = :d, payload = :p, "
                          "prev_hash = :prev, entry_hash = :e, leaf_hash = :l, leaf_bytes = :b WHERE seq = :seq"),
                     {"c": r["created_at"], "k": r["kind"], "s": r["serial"], "d": r["decision"], "p": r["payload"],
                      "prev": prev, "e": digest, "l": merkle.leaf_hash(body).hex(), "b": body, "seq": seq})
        prev = digest


def _content(conn) -> dict[int, dict]:
    result = conn.execute(text("SELECT seq, created_at, kind, serial, decision, payload FROM audit_log"))
    return {int(r.seq): dict(r._mapping) for r in result}


# --- item 3: no new key, no signature over entries no trusted head vouches for -------------------

def _forget_every_head(url: str, *, key: bool) -> None:
    drop_triggers(url)
    with get_engine(url).begin() as conn:
        conn.exec_driver_sql("DELETE FROM audit_tree_heads")
    key_file, sth_log, latest = _files(url)
    for p in (sth_log, latest) + ((key_file,) if key else ()):
        p.unlink()


@pytest.fixture(scope="module")
def genuine(tmp_path_factory) -> Path:
    """A recorded flight whose check is decided and audited (inconclusive: exit 4)."""
    return write_m300_flight(tmp_path_factory.mktemp("trust"))


def test_no_new_key_over_a_log_with_entries(db_url: str, genuine: Path, capsys) -> None:
    """Every head deleted (database, STH log, latest-head file) and the key file too: the next
    `authn check` exits 3 with one line, makes no key and appends nothing; verify exits 1."""
    from authn.demo import register_examples

    register_examples(db_url)
    _fill(db_url)
    _forget_every_head(db_url, key=True)
    capsys.readouterr()
    assert main(["--db", db_url, "check", str(genuine)]) == 3
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "missing but the log has entries" in err and "authn audit recover" in err
    assert not _files(db_url)[0].exists()
    with get_engine(db_url).begin() as conn:
        assert conn.exec_driver_sql("SELECT COUNT(*) FROM audit_log").scalar_one() == 10
    code, out = _verify(db_url, capsys)
    assert code == 1 and "entries 1..10 are covered by no signed tree head" in out


def test_no_signature_over_a_log_whose_heads_were_deleted(db_url: str, capsys) -> None:
    """The key kept, every head deleted: the writer does not sign over what nothing vouches for
    (a database writer could have rewritten it with the chain recomputed)."""
    _fill(db_url)
    _forget_every_head(db_url, key=False)
    with pytest.raises(SystemFault, match="holds 10 entries but no signed head vouches for them.*recover"):
        _next_append(db_url)
    assert main(["--db", db_url, "audit", "checkpoint"]) == 1
    assert "covered by no signed tree head" in capsys.readouterr().err


@pytest.mark.parametrize("key", [True, False], ids=["key-lost", "key-kept"])
def test_recover_signs_the_log_as_it_stands(db_url: str, capsys, key: bool) -> None:
    _fill(db_url)
    _forget_every_head(db_url, key=key)
    capsys.readouterr()
    assert main(["--db", db_url, "audit", "recover"]) == 2  # names what it would trust, changes nothing
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "holds 10 entries (0 vouched for by a signed head)" in err
    root = err.split("--trust-root ")[-1].strip()
    assert len(root) == 64
    assert main(["--db", db_url, "audit", "recover", "--trust-root", "0" * 64]) == 2
    assert main(["--db", db_url, "audit", "recover", "--trust-root", root]) == 0
    assert "recovered: entries 1..10" in capsys.readouterr().out
    assert _verify(db_url, capsys)[0] == 0
    _next_append(db_url)
    assert _verify(db_url, capsys)[0] == 0
    db = Database(db_url)
    entries = list_entries(db)
    db.close()
    audit = entries[10]
    assert (audit.seq, audit.kind) == (11, "audit")
    assert audit.payload["trusted"]["entries"] == 10 and audit.payload["trusted"]["tree_root"] == root
    assert audit.payload["new_key"] is key
    assert main(["--db", db_url, "audit", "recover"]) == 0  # nothing left to recover
    assert "nothing to recover" in capsys.readouterr().out


def test_recover_refuses_a_log_a_signed_head_contradicts(db_url: str, capsys) -> None:
    """Recover signs what nothing vouches for; it does not overrule a head that still exists."""
    _fill(db_url)
    drop_triggers(db_url)
    with get_engine(db_url).begin() as conn:
        rows = _content(conn)
        rows[3]["decision"] = "accept" if rows[3]["decision"] == "reject" else "reject"
        _recompute(conn, rows, 3, 10)
        conn.exec_driver_sql("DELETE FROM audit_tree_heads WHERE tree_size > 8")
    _files(db_url)[2].unlink()
    capsys.readouterr()
    assert main(["--db", db_url, "audit", "recover", "--trust-root", "0" * 64]) == 1
    assert "does not verify" in capsys.readouterr().err


# --- item 4: the stored right edge does not move the writer's anchor -----------------------------

def _edges(conn) -> list[tuple[int, int]]:
    """(id, tree_size) of the heads that keep a right edge, newest last."""
    return [(int(i), int(n)) for i, n in conn.exec_driver_sql(
        "SELECT id, tree_size FROM audit_tree_heads WHERE frontier IS NOT NULL ORDER BY tree_size, id")]


def _frontier(conn, size: int) -> merkle.Frontier:
    f = merkle.Frontier()
    for (h,) in conn.exec_driver_sql(f"SELECT leaf_hash FROM audit_log WHERE seq <= {size} ORDER BY seq"):
        f.push(bytes.fromhex(h))
    return f


def _edit_payload(conn, seq: int) -> None:
    """An edit that leaves the hash columns as they are (the chain breaks locally)."""
    conn.execute(text("UPDATE audit_log SET payload = :p WHERE seq = :s"), {"p": '{"reasons":["x"]}', "s": seq})


def test_an_old_form_edge_does_not_hide_an_edit_of_the_anchor_entry(db_url: str) -> None:
    """The newest periodic head's edge rewritten in the pre-0005 list form (the right edge at
    its size, computed from the stored leaves), then the entry at its size edited: the writer
    took that entry as stored and appended."""
    _fill(db_url)
    drop_triggers(db_url)
    with get_engine(db_url).begin() as conn:
        head_id, b = _edges(conn)[-1]
        edge = json.dumps([h.hex() for h in _frontier(conn, b).hashes])
        conn.execute(text("UPDATE audit_tree_heads SET frontier = :f WHERE id = :i"), {"f": edge, "i": head_id})
        _edit_payload(conn, b)
    with pytest.raises(SystemFault, match=f"entry {b} was modified"):
        _next_append(db_url)


def test_an_edge_put_on_a_newer_head_does_not_move_the_anchor(db_url: str) -> None:
    """A right edge written onto the newest (not periodic) head moved the anchor past an edit
    between the periodic head and it: the writer no longer re-hashed that entry."""
    _fill(db_url, 12)  # periodic heads at 1, 5 and 9
    drop_triggers(db_url)
    with get_engine(db_url).begin() as conn:
        (_, periodic), = _edges(conn)[-1:]
        newest_id, size = conn.exec_driver_sql(
            "SELECT id, tree_size FROM audit_tree_heads ORDER BY tree_size DESC, id DESC LIMIT 1").one()
        assert size > periodic + 1
        edge = json.dumps({"before_last": [h.hex() for h in _frontier(conn, size - 1).hashes]})
        conn.execute(text("UPDATE audit_tree_heads SET frontier = :f WHERE id = :i"), {"f": edge, "i": newest_id})
        _edit_payload(conn, periodic + 1)
    with pytest.raises(SystemFault, match=f"entry {periodic + 1} was modified"):
        _next_append(db_url)


# --- item 5: one stored form per instant ----------------------------------------------------------

def test_a_time_rewritten_in_another_offset_fails(db_url: str, capsys) -> None:
    """created_at of entry 6 (after the last periodic head, 5) rewritten as the same instant at
    UTC-23:59: SQLite keeps the text, which is not the writer's form (verify names entry 6; the
    next append refuses); PostgreSQL's timestamptz stores the instant, so nothing changes there."""
    _fill(db_url, 7)
    drop_triggers(db_url)
    pg = get_engine(db_url).dialect.name == "postgresql"
    offset = timezone(-timedelta(hours=15 if pg else 23, minutes=59))  # PostgreSQL's widest offset is 15:59
    with get_engine(db_url).begin() as conn:
        before = conn.exec_driver_sql("SELECT created_at FROM audit_log WHERE seq = 6").scalar()
        instant = Database.from_db_time(before)
        shifted = instant.astimezone(offset).isoformat(timespec="microseconds")
        conn.execute(text("UPDATE audit_log SET created_at = :c WHERE seq = 6"), {"c": shifted})
        after = conn.exec_driver_sql("SELECT created_at FROM audit_log WHERE seq = 6").scalar()
    db = Database(db_url)
    listed = [e.seq for e in list_entries(db, since=instant)]
    db.close()
    assert listed[0] == 6  # --since compares instants
    code, out = _verify(db_url, capsys)
    if pg:
        assert after == before and code == 0
        return
    assert after == shifted and code == 1 and "BROKEN at entry 6" in out and "created_at" in out
    with pytest.raises(SystemFault, match="entry 6 is malformed"):
        _next_append(db_url)


# --- item 6: every damaged head source is reported ------------------------------------------------

def test_a_garbage_sth_log_does_not_verify(db_url: str, capsys, tmp_path: Path) -> None:
    _fill(db_url)
    _, sth_log, latest = _files(db_url)
    assert _verify(db_url, capsys)[0] == 0
    good = sth_log.read_bytes()
    sth_log.write_bytes(os.urandom(4096))
    code, out = _verify(db_url, capsys)
    assert code == 1 and f"STH log {sth_log}" in out and out.count("\n") == 1
    sth_log.write_bytes(good)
    code, out = _verify(db_url, capsys, "--sth-log", str(tmp_path / "nonexistent"))
    assert code == 2 and "no such file" in out
    binary = tmp_path / "binary.jsonl"
    binary.write_bytes(b"\x00\xff" * 512)
    assert _verify(db_url, capsys, "--sth-log", str(binary))[0] == 1
    latest.write_bytes(b"not a head")
    code, out = _verify(db_url, capsys)
    assert code == 1 and "latest-head file" in out


# --- item 10: the first entry that differs, stored leaf hashes -----------------------------------

def test_verify_names_the_first_rewritten_entry(db_url: str, capsys) -> None:
    """Entries 3..8 rewritten with their chain recomputed (entry 9 left to break): entry 3."""
    _fill(db_url)
    drop_triggers(db_url)
    with get_engine(db_url).begin() as conn:
        rows = _content(conn)
        for seq in range(3, 9):
            rows[seq]["decision"] = "accept" if rows[seq]["decision"] == "reject" else "reject"
        _recompute(conn, rows, 3, 8)
    code, out = _verify(db_url, capsys)
    assert code == 1 and "BROKEN at entry 3:" in out and "entry 9 does not link to entry 8" in out


def test_verify_names_the_first_of_two_swapped_entries(db_url: str, capsys) -> None:
    _fill(db_url)
    drop_triggers(db_url)
    with get_engine(db_url).begin() as conn:
        rows = _content(conn)
        rows[3], rows[4] = rows[4], rows[3]
        _recompute(conn, rows, 3, 4)
    code, out = _verify(db_url, capsys, "--json")
    doc = json.loads(out)
    assert code == 1 and doc["first_bad_seq"] == 3 and not doc["ok"]


def test_a_null_leaf_hash_fails_verify(db_url: str, capsys) -> None:
    _fill(db_url)
    drop_triggers(db_url)
    with get_engine(db_url).begin() as conn:
        conn.exec_driver_sql("UPDATE audit_log SET leaf_hash = NULL WHERE seq = 4")
    code, out = _verify(db_url, capsys)
    assert code == 1 and "BROKEN at entry 4: entry 4: stored leaf hash is missing" in out


# --- item 9: malformed rows name their entry; deep JSON is bad input ------------------------------

@pytest.mark.parametrize("column", ["serial", "created_at"])
def test_a_row_of_the_wrong_type_fails_verify_at_its_entry(db_url: str, capsys, column: str) -> None:
    """A BLOB serial or an integer created_at (SQLite stores what it is given; on PostgreSQL the
    column's type is altered, so every row changes and entry 1 is the first)."""
    _fill(db_url, 6)
    drop_triggers(db_url)
    engine = get_engine(db_url)
    with engine.begin() as conn:
        if engine.dialect.name == "sqlite":
            value = "X'DEADBEEF'" if column == "serial" else "1700000000"
            conn.exec_driver_sql(f"UPDATE audit_log SET {column} = {value} WHERE seq = 4")
            where = 4
        else:
            using = "serial::bytea" if column == "serial" else "extract(epoch FROM created_at)::bigint"
            kind = "bytea" if column == "serial" else "bigint"
            conn.exec_driver_sql(f"ALTER TABLE audit_log ALTER COLUMN {column} TYPE {kind} USING {using}")
            where = 1
    code, out = _verify(db_url, capsys)
    assert code == 1 and f"BROKEN at entry {where}:" in out and f"entry {where} is malformed: {column}" in out
    assert out.count("\n") == 1


def test_deeply_nested_json_is_bad_input(db_url: str, capsys, tmp_path: Path) -> None:
    _fill(db_url, 2)
    pub = tmp_path / "pub.pem"
    assert main(["--db", db_url, "audit", "public-key", "--out", str(pub)]) == 0
    deep_array = tmp_path / "deep-array.json"
    deep_array.write_text("[" * 100_000 + "]" * 100_000)
    deep_object = tmp_path / "deep-object.json"
    deep_object.write_text('{"a":' * 100_000 + "1" + "}" * 100_000)
    for args in (["audit", "verify-proof", str(deep_array), "--public-key", str(pub)],
                 ["audit", "verify-proof", str(deep_object), "--public-key", str(pub)],
                 ["--db", db_url, "audit", "verify", "--against", str(deep_object)]):
        capsys.readouterr()
        assert main(args) == 2, args
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "Traceback" not in err
