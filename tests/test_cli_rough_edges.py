"""The front door's rough edges, each with the behaviour a new user expects."""

from __future__ import annotations

import json
from pathlib import Path

from authn.cli import main

OCTO = {"profiles": [{"slug": "octo-x8", "name": "Octocopter X8", "rotors": 8, "arms": 8, "blades_per_rotor": 2,
                      "blade_length_m": 0.38, "rotor_rate_hz": 45.0, "propeller_distance_m": 1.0}]}


def test_simulate_then_register_then_check_accepts(tmp_path: Path, capsys) -> None:
    """The order people try first: the recordings are older than the registration by the time
    it takes to type the command; the default validity window starts 24 h back. A single check is
    a track of one dwell, which at the default targets radar alone never accepts (one dwell counts
    at most 4 nats, the accept bound is 6.90): the flow that accepts simulates a track
    (`simulate --track`) and checks it (`check --track`); one of its dwells alone is inconclusive."""
    db = f"sqlite:///{tmp_path / 'r.sqlite3'}"
    track = tmp_path / "genuine"
    assert main(["simulate", "--model", "m300", "--range", "500", "--speed", "4", "--rid-serial",
                 "1581BDEM00000042", "--track", "5", "--out", f"{track}/"]) == 0
    assert main(["--db", db, "register", "--serial", "1581BDEM00000042", "--model", "m300"]) == 0
    capsys.readouterr()
    assert main(["--db", db, "check", "--track", str(track), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["decision"] == "accept" and out["reasons"] == ["registered-active"] and out["llr"] >= 6.90
    assert out["dwells"] and all(out["registry"]["valid_from"] < d["dwell_start"] for d in out["dwells"])
    assert main(["--db", db, "check", str(track / "dwell_000000.h5"), "--json"]) == 4
    one = json.loads(capsys.readouterr().out)
    assert one["decision"] == "inconclusive" and one["reasons"] == ["radar-inconclusive"]  # not outside the window
    assert one["registry"]["valid_from"] < one["dwell_start"]


def test_outside_the_window_says_both_times(tmp_path: Path, capsys) -> None:
    db = f"sqlite:///{tmp_path / 'r.sqlite3'}"
    flight = tmp_path / "old.h5"
    assert main(["simulate", "--model", "m300", "--range", "500", "--rid-serial", "1581BDEM00000042",
                 "--start-time", "2025-06-01T12:00:00Z", "--out", str(flight)]) == 0
    assert main(["--db", db, "register", "--serial", "1581BDEM00000042", "--model", "m300"]) == 0
    capsys.readouterr()
    assert main(["--db", db, "check", str(flight)]) == 1
    out = capsys.readouterr().out
    assert "outside-validity-window" in out and "dwell at 2025-06-01T12:00:00" in out and "valid from" in out


def test_count_with_a_file_name_is_refused(tmp_path: Path, capsys) -> None:
    target = tmp_path / "x.h5"
    assert main(["simulate", "--model", "m300", "--range", "500", "--count", "3", "--out", str(target)]) == 2
    assert "give a directory" in capsys.readouterr().err and not target.exists()


def test_profiles_file_adds_to_the_shipped_ones(tmp_path: Path) -> None:
    extra = tmp_path / "my-profiles.json"
    extra.write_text(json.dumps(OCTO))
    for model in ("octo-x8", "m300"):
        assert main(["simulate", "--model", model, "--range", "300", "--profiles", str(extra),
                     "--out", str(tmp_path / f"{model}.h5")]) == 0


def test_version(capsys) -> None:
    assert main(["--version"]) == 0
    assert capsys.readouterr().out.startswith("authn ")


def test_list_tables_fit_80_columns(tmp_path: Path, capsys, monkeypatch) -> None:
    """`registry list` and `audit list` stay readable in a standard terminal: no cell of the
    serial or decision truncated with an ellipsis. (On a terminal: piped, they are tab-separated
    lines, tests/test_cli_output.py.)"""
    from authn.cli import output
    from authn.demo import register_examples

    monkeypatch.setenv("COLUMNS", "80")
    monkeypatch.setattr(output, "is_terminal", lambda: True)
    db = f"sqlite:///{tmp_path / 'r.sqlite3'}"
    register_examples(db)
    assert main(["--db", db, "check", str(tmp_path / "missing.h5"), "--serial", "1581BDEM00000002"]) == 2
    capsys.readouterr()
    for command in (["registry", "list"], ["audit", "list"]):
        assert main(["--db", db, *command]) == 0
        out = capsys.readouterr().out
        assert max(len(line) for line in out.splitlines()) <= 80 and "…" not in out, out


def test_db_option_after_the_subcommand(tmp_path: Path, capsys) -> None:
    db = f"sqlite:///{tmp_path / 'r.sqlite3'}"
    assert main(["register", "--serial", "1581BDEM00000042", "--model", "m300", "--db", db]) == 0
    capsys.readouterr()
    assert main(["registry", "list", "--json", f"--db={db}"]) == 0
    assert [r["serial"] for r in json.loads(capsys.readouterr().out)] == ["1581BDEM00000042"]


def test_signing_and_trust_options_refuse_bad_input_in_one_line(tmp_path: Path, capsys) -> None:
    """Each new DRIP option's bad input: exit 2, one `error:` line, no traceback."""
    key = tmp_path / "ua.pem"
    assert main(["keys", "generate", "--out", str(key)]) == 0
    garbage = tmp_path / "garbage.json"
    garbage.write_text("{not json")
    flight = ["simulate", "--model", "m300", "--range", "500", "--rid-serial", "1581BDEM00000042",
              "--out", str(tmp_path / "s.h5")]
    cases = [
        ["keys", "generate", "--out", str(key)],  # never overwrites a key
        ["keys", "generate", "--out", str(tmp_path / "k2.pem"), "--raa", "99999"],
        [*flight, "--sign-key", str(garbage)],
        [*flight, "--sign-key", str(key), "--sam", "envelope"],
        [*flight, "--sign-key", str(key), "--sign-det", "not-a-det"],
        ["simulate", "--model", "m300", "--range", "500", "--out", str(tmp_path / "t.h5"), "--sign-key", str(key)],
        ["check", str(tmp_path / "s.h5"), "--serial", "1581BDEM00000042", "--trust-registry", str(garbage)],
    ]
    for argv in cases:
        capsys.readouterr()
        assert main(["--db", f"sqlite:///{tmp_path / 'r.sqlite3'}", *argv]) == 2, argv
        err = "".join(line for line in capsys.readouterr().err.splitlines(keepends=True)
                      if not line.startswith("authn: created new database "))  # the first one creates it
        assert err.startswith("error: ") and err.count("\n") == 1 and "Traceback" not in err, (argv, err)


def test_simulate_refuses_an_unknown_domain_in_one_line(tmp_path: Path, capsys) -> None:
    out = tmp_path / "x.h5"
    assert main(["simulate", "--model", "m300", "--range", "300", "--domain", "fmcw", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.splitlines() == [err] and "--domain: 'fmcw' is not one of if, range, cw" in err
    assert not out.exists()


def test_usage_errors_are_one_line_bad_input(capsys) -> None:
    """Unknown options, commands, missing arguments and unparsable values exit 2 with one line
    naming the command's help: no boxed usage text, no traceback."""
    cases = {("check", "--bogus"): "authn check --help", ("nosuch",): "authn --help",
             ("check",): "Missing argument", ("simulate", "--model", "m300", "--range", "abc"): "'--range'",
             ("registry", "list", "--nope"): "authn registry list --help"}
    for argv, needle in cases.items():
        capsys.readouterr()
        assert main(list(argv)) == 2, argv
        err = capsys.readouterr().err
        assert err.startswith("error: ") and err.count("\n") == 1 and needle in err, (argv, err)


def test_a_bare_group_still_prints_its_help(capsys) -> None:
    assert main(["registry"]) == 2
    assert "Usage" in capsys.readouterr().out
