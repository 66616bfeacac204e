"""System faults exit 3 in one line, a policy or engine error never accepts, and no decision
is printed that the audit did not commit."""

from __future__ import annotations

import json
import os
import sqlite3
import subprocess
import sys
from pathlib import Path

import pytest

from tests.flights import write_m300_flight

from authn.cli import main
from authn.demo import register_examples

M300 = "1581BDEM00000002"


@pytest.fixture(scope="module")
def genuine(tmp_path_factory) -> Path:
    return write_m300_flight(tmp_path_factory.mktemp("faults"))


@pytest.fixture
def db(tmp_path: Path) -> str:
    url = f"sqlite:///{tmp_path / 'r.sqlite3'}"
    register_examples(url)
    return url


def _sqlite(url: str) -> sqlite3.Connection:
    return sqlite3.connect(url.removeprefix("sqlite:///"), isolation_level=None)


def _one_error_line(err: str) -> None:
    assert err.startswith("error: ") and err.count("\n") == 1 and "Traceback" not in err, err


def _audit_rows(url: str) -> list[tuple]:
    with _sqlite(url) as conn:
        return conn.execute("SELECT kind, decision, payload FROM audit_log ORDER BY seq").fetchall()


def test_genuine_accepts_before_any_fault(genuine: Path, db: str, capsys) -> None:
    """The baseline the fault tests break: this file and registry give a decision, exit 4 (one
    unsigned dwell is inconclusive at the default error targets, docs/policies.md)."""
    assert main(["--db", db, "check", str(genuine)]) == 4


def test_failed_audit_write_prints_no_decision_and_exits_3(genuine: Path, db: str, capsys) -> None:
    with _sqlite(db) as conn:  # a database that refuses the insert, as a full disk or a revoked grant would
        conn.execute("CREATE TRIGGER refuse BEFORE INSERT ON audit_log BEGIN SELECT RAISE(ABORT, 'disk full'); END")
    capsys.readouterr()
    assert main(["--db", db, "check", str(genuine), "--json"]) == 3
    out, err = capsys.readouterr()
    assert out == ""  # the decision was made but is not printed: it is not in the audit
    _one_error_line(err)
    assert "disk full" in err


def test_lock_held_past_the_timeout_exits_3(genuine: Path, db: str, capsys, monkeypatch) -> None:
    import registry.dbapi

    monkeypatch.setattr(registry.dbapi, "LOCK_TIMEOUT_S", 0.2)
    holder = _sqlite(db)
    holder.execute("BEGIN EXCLUSIVE")
    try:
        capsys.readouterr()
        assert main(["--db", db, "check", str(genuine)]) == 3
        out, err = capsys.readouterr()
    finally:
        holder.execute("ROLLBACK")
        holder.close()
    assert "ACCEPT" not in out
    _one_error_line(err)
    assert "locked" in err


def test_unopenable_database_exits_3(genuine: Path, tmp_path: Path, capsys) -> None:
    blocker = tmp_path / "not-a-dir"
    blocker.write_text("a file where the database directory should be")
    assert main(["--db", f"sqlite:///{blocker / 'r.sqlite3'}", "check", str(genuine), "--serial", M300]) == 3
    _one_error_line(capsys.readouterr().err)


def test_policy_engine_exception_exits_3_and_is_audited(genuine: Path, db: str, capsys, monkeypatch) -> None:
    import cedarpy

    def broken(*_args, **_kwargs):
        raise RuntimeError("engine exploded")

    monkeypatch.setattr(cedarpy, "is_authorized", broken)
    capsys.readouterr()
    assert main(["--db", db, "check", str(genuine), "--json"]) == 3
    out, err = capsys.readouterr()
    assert out == ""
    _one_error_line(err)
    assert "policy engine" in err
    (kind, decision, payload), = _audit_rows(db)
    assert kind == "error" and decision is None and json.loads(payload)["error_kind"] == "system"


ERRORING_FORBID = """
@id("overflowing-check")
forbid (principal, action == Action::"authenticate", resource)
when { principal.valid_from_s + 9223372036854775807 > 0 };
"""


def test_policy_whose_forbid_errors_rejects(genuine: Path, db: str, tmp_path: Path, capsys) -> None:
    """Cedar skips a policy whose condition errors: without the check, this forbid would let the
    genuine claim through."""
    from importlib import resources

    text = resources.files("authn.policies").joinpath("default.cedar").read_text() + ERRORING_FORBID
    policy = tmp_path / "site.cedar"
    policy.write_text(text)
    capsys.readouterr()
    assert main(["--db", db, "check", str(genuine), "--policy", str(policy), "--json"]) == 1
    out = json.loads(capsys.readouterr().out)
    assert out["decision"] == "reject" and "policy-error" in out["reasons"]
    assert out["policy_errors"] and "overflow" in " ".join(out["policy_errors"]).lower()
    (kind, decision, payload), = _audit_rows(db)
    assert decision == "reject" and json.loads(payload)["policy_errors"] == out["policy_errors"]


def test_audit_payload_carries_the_exact_cedar_request(genuine: Path, db: str, capsys) -> None:
    """What `authn audit replay` re-evaluates: the same request gives the same decision."""
    from authn.policy import PolicyEngine

    assert main(["--db", db, "check", str(genuine)]) == 4
    (_, decision, payload), = _audit_rows(db)
    doc = json.loads(payload)
    request = doc["policy_input"]
    assert request["serial"] == M300 and request["context"]["radar_run"] is True
    replayed = PolicyEngine.load().decide(request["serial"], request["principal"], request["resource"],
                                          request["context"])
    assert replayed.decision == decision == "inconclusive" and replayed.reasons == doc["reasons"]


def test_unexpected_exception_is_one_line_exit_3_and_audited(genuine: Path, db: str, capsys,
                                                             monkeypatch) -> None:
    import authn.check

    def crash(*_args, **_kwargs):
        raise OverflowError("date value out of range")

    monkeypatch.setattr(authn.check, "read_claim", crash)
    capsys.readouterr()
    assert main(["--db", db, "check", str(genuine)]) == 3
    err = capsys.readouterr().err
    _one_error_line(err)
    assert "OverflowError" in err
    (kind, _, payload), = _audit_rows(db)
    assert kind == "error" and "OverflowError" in json.loads(payload)["error"]


def test_fresh_machine_bad_file_is_one_line_exit_2(tmp_path: Path) -> None:
    """Before any other command has created the default database (a new HOME)."""
    home = tmp_path / "home"
    home.mkdir()
    bad = tmp_path / "not-an-hdf5.h5"
    bad.write_text("hello")
    env = {k: v for k, v in os.environ.items() if not k.startswith(("XDG_", "AUTHN_"))}
    env["HOME"] = str(home)
    proc = subprocess.run([sys.executable, "-m", "authn", "check", str(bad), "--serial", "1581A0000000001"],
                          capture_output=True, text=True, env=env, timeout=120)
    assert proc.returncode == 2, proc.stderr
    notice, _, error = proc.stderr.partition("\n")
    created = home.rglob("registry.sqlite3")
    assert notice.startswith("authn: created new database sqlite:///") and notice.endswith("(empty registry)"), \
        "creating the default database on first use says so, in one line"
    _one_error_line(error)
    assert list(created), "the failed check is audited in the default database"
