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

from tests.audit_tools import drop_triggers
from tests.flights import write_m300_flight

from authn.audit import merkle
from authn.audit import NewEntry, append, checkpoint, leaf, verify
from core.errors import SystemFault
from authn.audit.logkey import LogKey
from authn.audit.tree_head import SignedTreeHead
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
    return leaf.time_text(Database.from_db_time(v))


def _rewrite(conn, rows: list[list]) -> None:
    """Replace the whole log by `rows`, recomputing chain and leaf hashes (a careful forger)."""
    conn.exec_driver_sql("DELETE FROM audit_log")
    prev = "0" * 64
    for i, (_, created, kind, serial, decision, payload) in enumerate(rows, start=1):
        body = leaf.encode(i, _iso(created), kind, serial, decision, payload, prev)
        digest = hashlib.sha256(body).hexdigest()
        conn.exec_driver_sql(
            "INSERT INTO audit_log (seq, created_at, kind, serial, decision, payload, prev_hash, entry_hash, "
            "leaf_hash, leaf_bytes) VALUES (%s)" % ", ".join(["?" if conn.dialect.name == "sqlite" else "%s"] * 10),
            (i, created, kind, serial, decision, payload, prev, digest, merkle.leaf_hash(body).hex(), body))
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
    from authn.audit.head_files import latest_head_path, read_latest_head, sth_log_path

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


def _assert_next_append_refused(db_url: str) -> None:
    db = Database(db_url)
    try:
        with pytest.raises(SystemFault, match="audit log"):
            append(db, [NewEntry("decision", "NEXT", "reject", {"reasons": ["r"]})])
    finally:
        db.close()


@pytest.mark.parametrize("name", list(GROWING_OVER))
def test_append_refuses_to_grow_a_tampered_log(db_url: str, name: str) -> None:
    """The next decision is not appended over a truncated, extended or rewritten history
    (the writer checks the stored leaves against its latest signed head; content edits that
    keep the stored leaf hashes are verify's to find, above)."""
    tamper, where = GROWING_OVER[name]
    _setup(db_url)
    with get_engine(db_url).begin() as conn:
        tamper(conn, where)
    _assert_next_append_refused(db_url)


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


# --- the writer: every append proves the log extends what was signed ------------------------

def _launder(conn, first: int) -> None:
    """Entries `first`.. turned from accept to reject (and back), reasons edited, chain and
    leaf hashes recomputed with the project's own functions."""
    rows = _rows(conn)
    for row in rows[first - 1:]:
        row[4] = "reject" if row[4] == "accept" else "accept"
        row[5] = json.dumps({"reasons": ["laundered"]})
    _rewrite(conn, rows)


def _keys_dir() -> Path:
    from authn.audit.logkey import key_path

    return key_path().parent


def _latest_files() -> list[Path]:
    return list(_keys_dir().glob("*-latest-*.json"))


@pytest.fixture(scope="module")
def genuine(tmp_path_factory) -> Path:
    return write_m300_flight(tmp_path_factory.mktemp("tamper"))


def _checks(url: str, genuine: Path, n: int) -> None:
    from authn.cli import main

    for _ in range(n):
        assert main(["--db", url, "check", str(genuine)]) == 4  # inconclusive: decided and audited


def _count(url: str) -> int:
    with get_engine(url).begin() as conn:
        return conn.exec_driver_sql("SELECT COUNT(*) FROM audit_log").scalar_one()


@pytest.mark.parametrize("heads_too", [False, True], ids=["db-heads-kept", "db-heads-deleted"])
def test_laundering_after_the_last_periodic_head_is_refused(db_url: str, genuine: Path, heads_too: bool,
                                                            monkeypatch: pytest.MonkeyPatch, capsys) -> None:
    """The attack: periodic heads every K entries; entries after the last one rewritten
    (accept -> reject, reasons edited, hashes recomputed); the latest-head file deleted (and
    the per-commit heads in the database); then one ordinary check. The append is refused
    (exit 3, nothing appended) and `verify` fails."""
    from authn.cli import main
    from authn.demo import register_examples

    monkeypatch.setenv("AUTHN_AUDIT_CHECKPOINT_EVERY", "4")
    register_examples(db_url)
    _checks(db_url, genuine, 10)  # periodic heads at 4 and 8
    drop_triggers(db_url)
    with get_engine(db_url).begin() as conn:
        _launder(conn, 9)
        if heads_too:
            conn.exec_driver_sql("DELETE FROM audit_tree_heads WHERE tree_size > 8")
    for f in _latest_files():
        f.unlink()
    capsys.readouterr()
    assert main(["--db", db_url, "check", str(genuine)]) == 3
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "audit log" in err, err
    assert _count(db_url) == 10, "nothing appended to the laundered log"
    assert main(["--db", db_url, "audit", "verify"]) == 1
    assert "BROKEN" in capsys.readouterr().err


# rewrites before the last periodic head that keep the chain consistent: refused by the
# default (window) check; local edits too with AUTHN_AUDIT_APPEND_CHECK=full
RECHAINED = ["forged entry, chain recomputed", "rewrite and recompute the whole chain", "reorder, chain recomputed",
             "delete, chain recomputed", "delete the tail", "truncate all"]
LOCAL = ["edit an entry", "delete a middle entry", "reorder two entries"]
BEFORE = [(n, "window") for n in RECHAINED] + [(n, "full") for n in RECHAINED + LOCAL]


@pytest.mark.parametrize("name,mode", BEFORE, ids=[f"{n}-{m}" for n, m in BEFORE])
def test_tamper_before_the_last_periodic_head_stops_the_next_append(db_url: str, name: str, mode: str,
                                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    tamper, before, _ = TAMPERS[name]
    _setup(db_url)
    monkeypatch.setenv("AUTHN_AUDIT_APPEND_CHECK", mode)
    with get_engine(db_url).begin() as conn:
        tamper(conn, before)
    n = _count(db_url)
    _assert_next_append_refused(db_url)
    assert _count(db_url) == n


def test_local_edit_before_the_anchor_is_verifys_to_find_in_window_mode(db_url: str) -> None:
    """What the O(K) default does not see: a content edit before the last periodic head that
    leaves the hash columns alone. The append goes through; `verify` names the entry."""
    periodic, key = _setup(db_url)
    with get_engine(db_url).begin() as conn:
        _edit(conn, 3)
    db = Database(db_url)
    try:
        append(db, [NewEntry("decision", "NEXT", "reject", {"reasons": ["r"]})])
        report = verify(db, [periodic], public_key=key)
    finally:
        db.close()
    assert not report.ok and report.first_bad_seq == 3


def test_deleted_key_exits_3_and_no_new_key_is_made(db_url: str, genuine: Path, capsys) -> None:
    from authn.cli import main
    from authn.demo import register_examples
    from authn.audit.logkey import key_path

    register_examples(db_url)
    _checks(db_url, genuine, 2)
    key_path().unlink()
    capsys.readouterr()
    assert main(["--db", db_url, "check", str(genuine)]) == 3
    err = capsys.readouterr().err
    assert "is missing but the log has signed heads" in err and err.count("\n") == 1, err
    assert not key_path().exists(), "a new key was made behind the operator's back"
    assert main(["--db", db_url, "audit", "public-key"]) == 3
    assert not key_path().exists()
    assert _count(db_url) == 2


def test_heads_of_one_log_do_not_verify_for_another(tmp_path: Path, capsys) -> None:
    """Two logs, one key: log A's checkpoint names A's origin, so log B refuses it."""
    from authn.cli import main

    urls = [f"sqlite:///{tmp_path / name}.sqlite3" for name in ("a", "b")]
    for url in urls:
        db = Database(url)
        append(db, [NewEntry("decision", "S", "accept", {"reasons": ["r"]}) for _ in range(6)])
        db.close()
    head_a = tmp_path / "a-head.json"
    assert main(["--db", urls[0], "audit", "checkpoint", "--out", str(head_a)]) == 0
    assert main(["--db", urls[0], "audit", "verify", "--against", str(head_a)]) == 0
    capsys.readouterr()
    assert main(["--db", urls[1], "audit", "verify", "--against", str(head_a)]) == 1
    assert "names the log" in capsys.readouterr().err
    db_b = Database(urls[1])
    try:
        report = verify(db_b, [SignedTreeHead.read(head_a)], public_key=LogKey.load().public_key)
    finally:
        db_b.close()
    assert not report.ok and "names the log" in report.problem


@pytest.fixture(params=["folder", "http"])
def witness(request, tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    """A witness of the log's heads: a folder, or `authn audit witness serve` semantics over HTTP."""
    import threading

    from authn.audit import witness as w
    from tests.service.server import free_port

    store = tmp_path / "witness"
    if request.param == "folder":
        spec = str(store)
    else:
        port = free_port()

        class Keys(list):  # the log key exists only after the first append: resolve it per request
            def __iter__(self):
                return iter([LogKey.load().public_key])

        thread = threading.Thread(target=w.serve, args=(w.WitnessStore(store), Keys(), "127.0.0.1", port),
                                  daemon=True)
        thread.start()
        spec = f"http://127.0.0.1:{port}"
        import time as _t

        for _ in range(50):
            try:
                w.HttpWitness(spec).heads("x")
                break
            except SystemFault:
                _t.sleep(0.1)
    monkeypatch.setenv("AUTHN_AUDIT_WITNESS", spec)
    monkeypatch.setenv("AUTHN_AUDIT_CHECKPOINT_EVERY", "4")
    return spec


def test_rewrite_resigned_with_the_readable_key_is_reported_by_the_witness(db_url: str, witness: str,
                                                                          capsys) -> None:
    """An intruder who can read the log key rewrites the log, deletes every head kept on this
    machine and signs a fresh head over the rewrite. The witness holds heads the rewrite does
    not extend: it refuses the re-signed head, `verify` reports the log, and the next append
    is refused when it consults the witness."""
    from authn.audit import merkle as m
    from authn.audit import log_origin
    from authn.cli import main
    from authn.audit.witness import Conflict, open_witness

    db = Database(db_url)
    for i in range(8):
        append(db, [NewEntry("decision", f"S{i}", "accept", {"reasons": ["r"]})])
    origin = log_origin(db)
    db.close()
    held = open_witness(witness).heads(origin)
    assert [h.tree_size for h in held] == [1, 5]  # the first append is periodic, then every 4
    assert main(["--db", db_url, "audit", "verify"]) == 0
    drop_triggers(db_url)
    with get_engine(db_url).begin() as conn:
        _launder(conn, 2)
        conn.exec_driver_sql("DELETE FROM audit_tree_heads")
        leaves = [bytes.fromhex(h) for (h,) in conn.exec_driver_sql(
            "SELECT leaf_hash FROM audit_log ORDER BY seq").all()]
    for f in [*_latest_files(), _keys_dir() / "sth.jsonl", _keys_dir() / "audit-sth.jsonl"]:
        f.unlink(missing_ok=True)
    key = LogKey.load()  # the readable key
    forged = key.sign_tree_head(8, m.root_hash(leaves), 1, origin)
    with pytest.raises((Conflict, SystemFault)):
        open_witness(witness).add(forged, 8, [], [key.public_key])
    capsys.readouterr()
    assert main(["--db", db_url, "audit", "verify"]) == 1
    err = capsys.readouterr().err
    assert "witness" in err and "BROKEN" in err, err
    db = Database(db_url)
    try:
        with pytest.raises(SystemFault, match="audit log"):
            for i in range(4):  # the next periodic head asks the witness
                append(db, [NewEntry("decision", f"T{i}", "accept", {"reasons": ["r"]})])
    finally:
        db.close()


def test_rotate_key_hands_over_and_a_listed_stranger_is_not_trusted(db_url: str, tmp_path: Path, capsys) -> None:
    """`authn audit rotate-key`: the old key's heads stay valid through the head both keys
    signed; a key merely added to the retired-keys file vouches for nothing."""
    from authn.cli import main
    from authn.audit.logkey import create_key_file, key_path, retired_keys_path

    db = Database(db_url)
    append(db, [NewEntry("decision", f"S{i}", "accept", {"reasons": ["r"]}) for i in range(6)])
    old_id = LogKey.load().key_id
    assert main(["--db", db_url, "audit", "rotate-key"]) == 0
    out = capsys.readouterr().out
    assert "rotated: head of size 6" in out
    new = LogKey.load()
    assert new.key_id != old_id
    assert (key_path().parent / f"{key_path().name}.retired-{old_id[:16]}.pem").exists()
    append(db, [NewEntry("decision", "T", "reject", {"reasons": ["r"]})])
    assert main(["--db", db_url, "audit", "verify"]) == 0
    assert "ok: 7 entries" in capsys.readouterr().out
    stranger_path = tmp_path / "stranger.pem"
    create_key_file(stranger_path)
    stranger = LogKey.load(stranger_path)
    with open(retired_keys_path(key_path()), "a") as fh:
        fh.write(stranger.public_pem())
    from authn.audit._internal.headrows import store_head
    from authn.audit.heads import log_origin

    with db.write():
        store_head(db, stranger.sign_tree_head(7, b"\x00" * 32, 1, log_origin(db)), None)
    db.close()
    assert main(["--db", db_url, "audit", "verify"]) == 1
    assert "not signed by the log key" in capsys.readouterr().err


def test_checkpoint_note_is_a_c2sp_signed_note(db_url: str, tmp_path: Path, capsys) -> None:
    """`audit checkpoint --note`: origin, size, base64 root, our timestamp extension, a blank
    line and one signature line by the origin's key; `verify --against` reads it back."""
    import base64

    from authn.cli import main
    from authn.audit.tree_head import note_key_hash
    from core.pem import raw_public as public_raw

    db = Database(db_url)
    append(db, [NewEntry("decision", "S", "accept", {"reasons": ["r"]}) for _ in range(3)])
    db.close()
    note = tmp_path / "checkpoint"
    assert main(["--db", db_url, "audit", "checkpoint", "--note", "--out", str(note)]) == 0
    text = note.read_text()
    body, _, sig = text.partition("\n\n")
    origin, size, root, ext = body.split("\n")
    assert size == "3" and len(base64.b64decode(root)) == 32 and ext.startswith("authn-timestamp-ms ")
    dash, name, b64 = sig.strip().split(" ")
    raw = base64.b64decode(b64)
    key = LogKey.load().public_key
    assert dash == "\u2014" and name == origin and raw[:4] == note_key_hash(origin, public_raw(key))
    key.verify(raw[4:], (body + "\n").encode())  # the signature covers the note text, final newline included
    assert main(["--db", db_url, "audit", "verify", "--against", str(note)]) == 0


@pytest.mark.parametrize("body", [b"", b"old x\n\nnote", b"old 3\nnot-base64!\n\nnote", b"old 0\n\nno note",
                                  b"\xff\xfe", b"old 1\n" + b"QQ==\n" + b"\n"])
def test_a_malformed_add_checkpoint_request_is_bad_input(body: bytes) -> None:
    """What `authn audit witness serve` answers 400 to: anything that is not `old N`, base64
    32-byte proof hashes, a blank line and a signed note."""
    from authn.audit.witness import parse_add_request
    from core.errors import AuthnError

    with pytest.raises(AuthnError, match="add-checkpoint"):
        parse_add_request(body)
