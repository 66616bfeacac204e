"""Untrusted strings (import notes, model names, file names, serials, error messages) never
reach the operator's terminal raw: control and bidi characters come out escaped (`\\x1b`,
`\\u202e`) in human output and error lines, while --json stays exact JSON. Registry changes
in the audit log list as `registry`, not `error`."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from authn.cli import main
from core.textsafe import printable

ESC = "\x1b"
SERIAL = "1581F5FJD12345678901"
NOTES = "\x1b[31mred\x1b[0m \u202eevil\u202c \x9b31m bell\x07 end"
NAME = "Octo \x1b]0;owned\x07 [bold]X8[/bold]"


def run(capsys, db: str, *args: str) -> tuple[int, str, str]:
    """Exit code, stdout, stderr (without the notice that a new test database was created)."""
    code = main(["--db", db, *args])
    out, err = capsys.readouterr()
    return code, out, "".join(line for line in err.splitlines(keepends=True)
                              if not line.startswith("authn: created new database "))


@pytest.fixture(autouse=True)
def _wide_tables(monkeypatch) -> None:
    """Rich tables as wide as the rows: a cell's text stays on one line, findable."""
    monkeypatch.setenv("COLUMNS", "400")


def _no_raw_controls(text: str) -> None:
    assert ESC not in text and "\u202e" not in text and "\x9b" not in text and "\x07" not in text, text


@pytest.fixture
def db(tmp_path: Path) -> str:
    return f"sqlite:///{tmp_path / 'r.sqlite3'}"


def test_printable_escapes_c0_del_c1_and_bidi_and_keeps_the_rest() -> None:
    assert printable("a\x1b[31mb") == "a\\x1b[31mb"
    assert printable("\x00\t\n\r\x7f\x85\x9b") == "\\x00\\x09\\x0a\\x0d\\x7f\\x85\\x9b"
    assert printable("\u202aA\u202eB\u2066C\u2069\u200f") == "\\u202aA\\u202eB\\u2066C\\u2069\\u200f"
    assert printable("Åland 東京 ✈ C:\\path") == "Åland 東京 ✈ C:\\path"
    assert printable(42) == "42"


def _import_with_escapes(capsys, db: str, tmp_path: Path) -> None:
    doc = {"format": "authn-registry/1",
           "profiles": [{"slug": "x8", "name": NAME, "rotors": 8, "arms": 4, "blades_per_rotor": 2,
                         "blade_length_m": 0.38, "rotor_rate_hz": 45.0, "propeller_distance_m": 1.2}],
           "identities": [{"serial": SERIAL, "model": "x8", "notes": NOTES,
                           "valid_from": "2026-01-01T00:00:00+00:00"}]}
    path = tmp_path / "reg.json"
    path.write_text(json.dumps(doc))
    code, out, err = run(capsys, db, "registry", "import", str(path))
    assert code == 0, err


def test_registry_show_list_and_models_escape_imported_text(capsys, db: str, tmp_path: Path) -> None:
    _import_with_escapes(capsys, db, tmp_path)
    code, out, err = run(capsys, db, "registry", "show", SERIAL)
    assert code == 0
    _no_raw_controls(out + err)
    flat = "".join(out.split())  # the table may wrap the notes
    assert "\\x1b[31mred" in flat and "\\u202eevil" in flat and "\\x9b31m" in flat and "\\x07" in flat
    code, out, err = run(capsys, db, "registry", "models")
    assert code == 0
    _no_raw_controls(out + err)
    flat = "".join(out.split())
    assert "\\x1b]0;owned\\x07" in flat and "[bold]X8[/bold]" in flat  # rich markup stays text
    code, out, err = run(capsys, db, "registry", "list")
    assert code == 0 and SERIAL in out
    _no_raw_controls(out + err)


def test_json_output_stays_exact(capsys, db: str, tmp_path: Path) -> None:
    _import_with_escapes(capsys, db, tmp_path)
    code, out, _ = run(capsys, db, "registry", "show", SERIAL, "--json")
    assert code == 0
    _no_raw_controls(out)  # json.dumps escapes them (\u001b) ...
    assert json.loads(out)["notes"] == NOTES  # ... and the value round-trips exactly
    code, out, _ = run(capsys, db, "registry", "models", "--json")
    assert {p["slug"]: p["name"] for p in json.loads(out)}["x8"] == NAME


def test_error_lines_escape_serials(capsys, db: str) -> None:
    code, out, err = run(capsys, db, "registry", "show", "\x1b[2J\u202eX")
    assert code == 2 and err.startswith("error: ") and err.count("\n") == 1
    _no_raw_controls(out + err)
    assert "\\x1b[2J\\u202eX" in err
    code, _, err = run(capsys, db, "audit", "list", "--decision", "\x1b[5m")
    assert code == 2
    _no_raw_controls(err)


def test_usage_errors_escape_the_value(capsys) -> None:
    assert main(["audit", "\x1b[31mlist"]) == 2  # click's "No such command '...'" quotes it
    err = capsys.readouterr().err
    _no_raw_controls(err)
    assert "\\x1b[31mlist" in err and err.count("\n") == 1


def test_checked_file_name_with_escape_is_escaped_in_stderr_and_audit_list(capsys, db: str,
                                                                           tmp_path: Path) -> None:
    bad = tmp_path / "flight\x1b[2J\u202e.h5"
    bad.write_text("not an HDF5 file")
    code, out, err = run(capsys, db, "check", str(bad), "--serial", "1581BDEM00000002")
    assert code == 2 and err.rstrip("\n").splitlines()[-1].startswith("error: ")
    _no_raw_controls(out + err)
    assert "flight\\x1b[2J\\u202e.h5" in err
    code, out, err = run(capsys, db, "audit", "list")
    assert code == 0
    _no_raw_controls(out + err)
    assert "\\x1b[2J" in "".join(out.split())
    code, out, _ = run(capsys, db, "audit", "list", "--json")
    _no_raw_controls(out)
    assert [e["kind"] for e in json.loads(out)] == ["error"]


def test_batch_check_escapes_file_names(capsys, db: str, tmp_path: Path) -> None:
    folder = tmp_path / "batch"
    folder.mkdir()
    for name in ("a\x1b[31m.h5", "b\u202e.h5"):
        (folder / name).write_text("garbage")
    code, out, err = run(capsys, db, "check", str(folder), "--serial", "1581BDEM00000002")
    assert code == 2
    _no_raw_controls(out + err)
    assert "a\\x1b[31m.h5" in err and "b\\u202e.h5" in err


def test_registry_entries_list_as_registry_not_error(capsys, db: str) -> None:
    """`authn serve` audits registry changes (kind 'registry', no decision): the list says what
    changed and who changed it, and --decision registry selects them."""
    from authn.audit import NewEntry, append
    from registry.dbapi import Database

    assert run(capsys, db, "audit", "list", "--json")[0] == 0  # creates the database
    database = Database(db)
    append(database, [
        NewEntry("registry", SERIAL, None, {"action": "register", "api_key_id": 7, "role": "admin", "model": "m300"}),
        NewEntry("registry", SERIAL, None, {"action": "revoke", "api_key_id": 7, "role": "admin",
                                            "reason": "stolen \x1b[31m"}),
        NewEntry("registry", SERIAL, None, {"action": "register-failed", "api_key_id": 7, "role": "admin",
                                            "error": "serial 1581F5FJD12345678901: already registered"}),
        NewEntry("error", SERIAL, None, {"error": "flight.h5: not a readable HDF5 file"}),
    ])
    database.close()
    code, out, err = run(capsys, db, "audit", "list")
    assert code == 0, err
    _no_raw_controls(out)
    rows = [line for line in out.splitlines() if SERIAL[:8] in line]
    assert len(rows) == 4, out
    flat = "".join(out.split())
    assert "register(modelm300);byAPIkey7(admin)" in flat
    assert "revoke(reasonstolen\\x1b[31m)" in flat
    assert "register-failed;byAPIkey7(admin);serial1581F5FJD12345678901:alreadyregistered" in flat
    assert sum("registry" in row.split() for row in rows) == 3 and sum("error" in row.split() for row in rows) == 1, out
    code, out, _ = run(capsys, db, "audit", "list", "--decision", "registry", "--json")
    assert code == 0 and [e["payload"]["action"] for e in json.loads(out)] == ["register", "revoke",
                                                                              "register-failed"]
    code, out, _ = run(capsys, db, "audit", "list", "--decision", "error", "--json")
    assert [e["kind"] for e in json.loads(out)] == ["error"]
