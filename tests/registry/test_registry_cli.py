"""`authn register`, `registry ...` and `db upgrade` through the CLI entry point."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from registry.migrations import HEAD_REVISION

from authn.cli import main

SERIAL = "1581F5FJD12345678901"


def run(capsys, db_url, *args):
    """Exit code, stdout, stderr; stderr without the notice of a new database (the first
    command on a fresh test database creates it: tests/registry/test_db_url.py tests it)."""
    code = main(["--db", db_url, *args])
    out, err = capsys.readouterr()
    return code, out, "".join(line for line in err.splitlines(keepends=True)
                              if not line.startswith("authn: created new database "))


def test_register_list_show_revoke_export_import(capsys, db_url, tmp_path):
    key = tmp_path / "key.hex"
    key.write_text(bytes(range(32)).hex())
    assert run(capsys, db_url, "register", "--serial", SERIAL, "--model", "m300",
               "--operator-id", "FIN87astrdge12k", "--public-key", str(key))[0] == 0
    code, out, _ = run(capsys, db_url, "registry", "list", "--json")
    assert code == 0 and [r["serial"] for r in json.loads(out)] == [SERIAL]
    code, out, _ = run(capsys, db_url, "registry", "show", SERIAL, "--json")
    shown = json.loads(out)
    assert shown["profile"]["rotor_rate_hz"] == 40.0 and shown["public_key"] == bytes(range(32)).hex()
    code, out, _ = run(capsys, db_url, "registry", "list")
    assert code == 0 and SERIAL in out
    assert run(capsys, db_url, "registry", "revoke", SERIAL, "--reason", "stolen")[0] == 0
    csv_path = tmp_path / "out.csv"
    assert run(capsys, db_url, "registry", "export", "--out", str(csv_path))[0] == 0
    assert csv_path.read_text().startswith("serial,id_type,model,operator_id,valid_from")
    new = tmp_path / "new.csv"
    new.write_text("serial,model\n1581F5FJD12345678902,phantom4\nFA3ABC1234X,m600\n")
    code, _, err = run(capsys, db_url, "registry", "import", str(new))
    assert code == 2 and "line 3" in err  # FA3ABC1234X is no CTA-2063-A serial
    new.write_text("serial,id_type,model\n1581F5FJD12345678902,,phantom4\nFA3ABC1234X,caa_registration,m600\n")
    assert run(capsys, db_url, "registry", "import", str(new))[0] == 0
    code, out, _ = run(capsys, db_url, "registry", "list", "--status", "active", "--json")
    assert sorted(r["serial"] for r in json.loads(out)) == ["1581F5FJD12345678902", "FA3ABC1234X"]


def test_register_new_model_profile(capsys, db_url):
    code, out, _ = run(capsys, db_url, "register", "--serial", SERIAL, "--model", "x8", "--model-name",
                       "Octo X8", "--rotors", "8", "--arms", "4", "--blade-length", "0.38",
                       "--rotor-rate", "45", "--propeller-distance", "1.2", "--json")
    assert code == 0 and json.loads(out)["identity"]["profile"]["rotors"] == 8
    code, out, _ = run(capsys, db_url, "registry", "models", "--json")
    assert [p["slug"] for p in json.loads(out)] == ["m300", "m600", "phantom4", "x8"]


@pytest.mark.parametrize("args, match", [
    (["register", "--serial", "1581F5FJD123456789", "--model", "m300"], "length character"),
    (["register", "--serial", SERIAL, "--model", "nope"], "unknown model"),
    (["register", "--serial", SERIAL, "--model", "m300", "--valid-until", "tomorrow"], "ISO 8601"),
    (["register", "--serial", SERIAL, "--model", "m300", "--public-key", "/nonexistent"], "cannot read"),
    (["register", "--serial", SERIAL, "--model", "x9", "--rotors", "4"], "a new model needs"),
    (["register", "--model", "x9", "--model-name", "X", "--rotors", "3", "--arms", "2",
      "--blade-length", "0.3", "--rotor-rate", "40", "--propeller-distance", "0.5"], "multiple of arms"),
    (["register", "--model", "x9", "--model-name", "X", "--rotors", "4", "--blade-length", "30",
      "--rotor-rate", "40", "--propeller-distance", "0.5"], "blade_length_m"),
    (["registry", "show", SERIAL], "not registered"),
    (["registry", "revoke", SERIAL], "not registered"),
    (["registry", "list", "--status", "gone"], "--status"),
    (["registry", "import", "/nonexistent.csv"], "cannot read"),
])
def test_bad_input_is_one_line_exit_2(capsys, db_url, args, match):
    code, out, err = run(capsys, db_url, *args)
    assert code == 2, (out, err)
    assert err.startswith("error: ") and match in err and err.count("\n") == 1
    assert "Traceback" not in err


def test_bad_database_url_is_one_line(capsys):
    code = main(["--db", "nonsense://", "registry", "list"])
    err = capsys.readouterr().err
    assert code == 2 and err.startswith("error: ") and err.count("\n") == 1


def test_db_upgrade_and_env_var(db_url, tmp_path):
    env = {"AUTHN_DATABASE_URL": db_url, "PATH": "", "HOME": str(tmp_path)}
    proc = subprocess.run(
        [sys.executable, "-c", "import sys; from authn.cli import main; sys.exit(main(sys.argv[1:]))",
         "db", "upgrade"], env=env, capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    assert f"at revision {HEAD_REVISION}" in proc.stdout


@pytest.mark.parametrize("cmd", [["register"], ["registry", "list"], ["registry", "show"],
                                 ["registry", "revoke"], ["registry", "import"], ["registry", "export"],
                                 ["registry", "models"], ["db", "upgrade"], ["rid", "decode"]])
def test_every_command_has_help_with_example(capsys, cmd):
    assert main([*cmd, "--help"]) == 0
    assert "Example: authn " in capsys.readouterr().out
