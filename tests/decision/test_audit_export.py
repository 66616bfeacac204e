"""An audit log others can verify: each entry's leaf bytes stored and hashed as stored, `authn
audit export --dir`, and tools/verify_audit_export.py, which checks an export with hashlib and
cryptography alone (run here as a separate process on a log made by real checks)."""

from __future__ import annotations

import ast
import base64
import hashlib
import json
import subprocess
import sys
from pathlib import Path

import pytest
from sqlalchemy import text

from tests.audit_tools import drop_triggers
from tests.flights import write_m300_flight

from authn.audit import AuditLog, leaf, list_entries, merkle, verify
from authn.audit.tree_head import canonical_json
from authn.cli import main
from core.errors import EXIT_BAD_INPUT, EXIT_SYSTEM
from registry.db import get_engine
from registry.dbapi import Database

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "tools" / "verify_audit_export.py"


@pytest.fixture(autouse=True)
def _env(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("AUTHN_LOG_KEY", str(tmp_path / "keys" / "log.pem"))
    monkeypatch.setenv("AUTHN_AUDIT_STH_LOG", str(tmp_path / "keys" / "sth.jsonl"))


@pytest.fixture(scope="module")
def genuine(tmp_path_factory) -> Path:
    return write_m300_flight(tmp_path_factory.mktemp("export"))


def _run(folder: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(SCRIPT), str(folder)], capture_output=True, text=True, timeout=60)


def _checked_log(url: str, genuine: Path, tmp_path: Path) -> None:
    """Decisions and a failed check, each made by `authn check` and audited."""
    from authn.demo import register_examples

    register_examples(url)
    for _ in range(3):
        assert main(["--db", url, "check", str(genuine)]) == 4  # inconclusive: decided and audited
    bad = tmp_path / "bad.h5"
    bad.write_bytes(b"not hdf5")
    assert main(["--db", url, "check", str(bad)]) == EXIT_BAD_INPUT


def test_the_stored_leaf_bytes_are_what_is_hashed(db_url: str) -> None:
    db = Database(db_url)
    log = AuditLog(db, "permit(principal, action, resource);")
    log.record_decision("S1", "accept", {"reasons": ["é", "r"], "n": 1.5})
    log.record([AuditLog.error("f.h5", None, "not a readable HDF5 file", EXIT_BAD_INPUT, policy_sha256=None)])
    rows = db.fetch("SELECT seq, leaf_bytes, entry_hash, leaf_hash, payload FROM audit_log ORDER BY seq")
    for seq, body, entry_hash, leaf_hash, payload in rows:
        body = bytes(body)
        assert body[:1] == b"\x01" and hashlib.sha256(body).hexdigest() == entry_hash
        assert merkle.leaf_hash(body).hex() == leaf_hash
        doc = json.loads(body[1:])
        assert doc["seq"] == seq and doc["payload"] == json.loads(payload)  # the payload inline, not a string
        assert doc["created_at"].endswith("Z") and len(doc["created_at"]) == 27
        assert body[1:] == canonical_json(doc).encode()  # version 1 is canonical JSON after its byte
    assert verify(db).ok
    db.close()


def test_a_column_that_disagrees_with_the_bytes_is_reported(db_url: str, capsys) -> None:
    """The serial column rewritten, its chain and leaf hashes left: the bytes still hash right,
    the columns no longer say what they say."""
    db = Database(db_url)
    for i in range(3):
        AuditLog(db).record_decision(f"S{i}", "accept", {"reasons": ["r"]})
    db.close()
    drop_triggers(db_url)
    with get_engine(db_url).begin() as conn:
        conn.execute(text("UPDATE audit_log SET serial = 'EVIL' WHERE seq = 2"))
    capsys.readouterr()
    assert main(["--db", db_url, "audit", "verify"]) == 1
    err = capsys.readouterr().err
    assert "entry 2" in err and "disagree with its leaf bytes" in err


def test_audit_log_builds_the_error_payload(db_url: str) -> None:
    db = Database(db_url)
    log = AuditLog(db)
    bad = log.record([AuditLog.error("a.h5", "S", "truncated", EXIT_BAD_INPUT, policy_sha256=None)])[0]
    fault = log.record([AuditLog.error("b.h5", None, "disk", EXIT_SYSTEM, policy_sha256="0" * 64,
                                     track_files=["b.h5", "c.h5"])])[0]
    change = log.record_registry_change("S", "revoke", 7, "admin", {"reason": "x"})
    assert (bad.kind, bad.payload) == ("error", {"file": "a.h5", "error": "truncated", "error_kind": "bad-input",
                                                 "policy_sha256": None})
    assert fault.payload["error_kind"] == "system" and fault.payload["track_files"] == ["b.h5", "c.h5"]
    assert (change.kind, change.payload) == ("registry", {"action": "revoke", "api_key_id": 7, "role": "admin",
                                                          "reason": "x"})
    db.close()


def test_an_export_of_real_checks_verifies_outside_authn(db_url: str, genuine: Path, tmp_path: Path,
                                                         capsys) -> None:
    _checked_log(db_url, genuine, tmp_path)
    out = tmp_path / "export"
    assert main(["--db", db_url, "audit", "export", "--dir", str(out)]) == 0
    db = Database(db_url)
    report, kinds = verify(db), [e.kind for e in list_entries(db)]
    db.close()
    assert kinds == ["decision"] * 3 + ["error"]
    assert sorted(p.name for p in out.iterdir()) == ["checkpoint.txt", "leaves.jsonl", "log-key.pub.pem"]
    done = _run(out)
    assert done.returncode == 0, done.stderr
    assert done.stdout == f"OK: 4 entries, tree root {report.root}, checkpoint signed by the given key\n"

    lines = (out / "leaves.jsonl").read_text().splitlines()
    record = json.loads(lines[1])
    body = bytearray(base64.b64decode(record["leaf"]))
    body[body.index(b"inconclusive")] ^= 0x01  # one byte of one leaf
    record["leaf"] = base64.b64encode(bytes(body)).decode()
    (out / "leaves.jsonl").write_text("\n".join([lines[0], json.dumps(record), *lines[2:]]) + "\n")
    failed = _run(out)
    assert failed.returncode == 1 and failed.stdout == "" and failed.stderr.count("\n") == 1
    assert failed.stderr.startswith("FAILED: entry 3 does not link to entry 2")


@pytest.mark.parametrize("damage", ["flip a byte of the last leaf", "drop the last entry", "another key",
                                    "checkpoint root", "no checkpoint"])
def test_the_verifier_fails_an_export_that_does_not_hold(db_url: str, tmp_path: Path, damage: str) -> None:
    db = Database(db_url)
    AuditLog(db).record([AuditLog.decision(f"S{i}", "accept", {"reasons": ["r"]}) for i in range(5)])
    db.close()
    out = tmp_path / "export"
    assert main(["--db", db_url, "audit", "export", "--dir", str(out)]) == 0
    assert _run(out).returncode == 0
    if damage == "flip a byte of the last leaf":  # no later entry links to it: only the root can tell
        lines = (out / "leaves.jsonl").read_text().splitlines()
        record = json.loads(lines[-1])
        body = bytearray(base64.b64decode(record["leaf"]))
        body[body.index(b"S4")] ^= 0x01
        record["leaf"] = base64.b64encode(bytes(body)).decode()
        (out / "leaves.jsonl").write_text("\n".join([*lines[:-1], json.dumps(record)]) + "\n")
    elif damage == "drop the last entry":
        lines = (out / "leaves.jsonl").read_text().splitlines()
        (out / "leaves.jsonl").write_text("\n".join(lines[:-1]) + "\n")
    elif damage == "another key":
        from authn.audit.logkey import LogKey, create_key_file

        create_key_file(tmp_path / "other.pem")
        (out / "log-key.pub.pem").write_text(LogKey.load(tmp_path / "other.pem").public_pem())
    elif damage == "checkpoint root":
        note = (out / "checkpoint.txt").read_text().split("\n")
        note[2] = base64.b64encode(b"\x00" * 32).decode()
        (out / "checkpoint.txt").write_text("\n".join(note))
    else:
        (out / "checkpoint.txt").unlink()
    done = _run(out)
    assert done.returncode == 1 and done.stderr.startswith("FAILED: ") and done.stderr.count("\n") == 1


def test_the_verifier_is_small_and_imports_only_hashlib_cryptography_and_the_standard_library() -> None:
    source = SCRIPT.read_text()
    assert len(source.splitlines()) < 100
    roots = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            roots |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            assert node.level == 0
            roots.add(str(node.module).split(".")[0])
    assert "hashlib" in roots and "cryptography" in roots
    assert roots - {"cryptography"} <= set(sys.stdlib_module_names), roots


def test_version_1_leaf_bytes_are_the_documented_encoding() -> None:
    """0x01 || canonical JSON of the seven fields, the payload inlined as its object."""
    payload = {"reasons": ["ü"], "x": [1, 2.5, None, True]}
    body = leaf.encode(3, "2026-01-02T03:04:05.000006Z", "decision", None, "accept", canonical_json(payload),
                       "ab" * 32)
    assert body == b"\x01" + canonical_json({"seq": 3, "created_at": "2026-01-02T03:04:05.000006Z",
                                             "kind": "decision", "serial": None, "decision": "accept",
                                             "payload": payload, "prev_hash": "ab" * 32}).encode()
