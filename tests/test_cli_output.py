"""Issue 36, "a tool people enjoy using": waveform guidance, output that survives pipes and
80-column terminals, JSON on every reporting command (errors included), help everywhere.
Each CLI run here is at COLUMNS=80 and piped (capsys, or a subprocess with a pipe)."""

from __future__ import annotations

import contextlib
import io
import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from authn.cli import command, main, output

M300 = "1581BDEM00000042"
DRIP = "01" + "AB" * 16  # a 34-character DRIP session ID (registered by `register_examples` with keys)


@pytest.fixture(autouse=True)
def _eighty_columns(monkeypatch) -> None:
    monkeypatch.setenv("COLUMNS", "80")


def _commands(cmd=None, path=()):
    from authn.cli.reference import subcommands

    cmd = cmd or command()
    yield path, cmd
    for name, sub in sorted(subcommands(cmd, path).items()):  # plugin commands (the laboratory's) too
        yield from _commands(sub, (*path, name))


def _help(path: tuple[str, ...], flag: str = "-h") -> str:
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        assert main([*path, flag]) == 0, path
    return buf.getvalue()


# --- help -------------------------------------------------------------------------------------

def test_every_command_has_help_with_an_example_at_80_columns() -> None:
    """`-h` everywhere; an `Example:` line on every command and group; on/off flags without a
    `<bool>` type; no help text cut mid-word or truncated at 80 columns."""
    seen = 0
    for path, cmd in _commands():
        out = _help(path)
        flat = re.sub(r"[│╭╮╰╯─\s]+", " ", out)
        assert "Example" in out and re.search(r"^\s*Example[^:]*:", out, re.M), (path, out)
        assert "<bool>" not in out and "…" not in out, (path, out)
        assert max(len(line) for line in out.splitlines()) <= 80, path
        words = [w for text in [cmd.help or "", *(getattr(p, "help", None) or "" for p in cmd.params)]
                 for w in text.split() if "[" not in w and "]" not in w]
        assert [w for w in words if w not in flat] == [], path  # every word of the help shown whole
        seen += 1
    assert seen > 40 and _help(("registry", "list"), "--help") == _help(("registry", "list"), "-h")


def test_shell_completion_is_offered() -> None:
    out = _help(())
    assert "--install-completion" in out and "--show-completion" in out
    env = {**os.environ, "_AUTHN_COMPLETE": "complete_bash", "COMP_WORDS": "authn audi", "COMP_CWORD": "1"}
    run = subprocess.run([sys.executable, "-m", "authn"], capture_output=True, text=True, env=env, timeout=120)
    assert run.stdout.split() == ["audit"], run  # what the installed completion asks, answered


# --- tables -----------------------------------------------------------------------------------

def _world(tmp_path: Path) -> str:
    from authn.demo import DemoKeys, register_examples

    db = f"sqlite:///{tmp_path / 'r.sqlite3'}"
    register_examples(db, DemoKeys.generate())
    assert main(["--db", db, "register", "--serial", M300, "--model", "m300"]) == 0
    assert main(["--db", db, "check", str(tmp_path / "missing.h5"), "--serial", M300]) == 2
    return db


def test_piped_tables_are_one_tab_separated_line_per_result(tmp_path: Path, capsys) -> None:
    db = _world(tmp_path)
    capsys.readouterr()
    assert main(["--db", db, "registry", "list"]) == 0
    lines = capsys.readouterr().out.splitlines()
    serials = [line.split("\t")[0] for line in lines]
    assert all(line.count("\t") == 4 for line in lines) and M300 in serials
    assert any(len(s) == 34 and s.startswith("01") for s in serials)  # the DRIP session ID, whole
    assert main(["--db", db, "audit", "list"]) == 0
    rows = [line.split("\t") for line in capsys.readouterr().out.splitlines()]
    assert rows and all(len(r) == 5 for r in rows) and [r[2] for r in rows if r[3] == "error"] == [M300]
    assert main(["models", "list"]) == 0
    rows = [line.split("\t") for line in capsys.readouterr().out.splitlines()]
    assert [r[:3] for r in rows[:2]] == [["*", "paper", "shipped"], ["*", "wide", "shipped"]]  # * = active
    assert main(["--db", db, "registry", "models"]) == 0
    assert "m300\t" in capsys.readouterr().out


def test_piped_through_a_real_pipe(tmp_path: Path) -> None:
    run = subprocess.run([sys.executable, "-m", "authn", "models", "list"], capture_output=True, text=True,
                         env={**os.environ, "COLUMNS": "80"}, timeout=120)
    assert run.returncode == 0 and run.stdout.startswith("*\tpaper\tshipped\t600x80 at 77 GHz"), run


def test_tables_at_80_columns_never_split_identifiers(tmp_path: Path, capsys, monkeypatch) -> None:
    db = _world(tmp_path)
    monkeypatch.setattr(output, "is_terminal", lambda: True)
    capsys.readouterr()
    for argv, whole in ((["registry", "list"], [M300, "registered"]), (["audit", "list"], [M300]),
                        (["models", "list"], ["paper", "shipped", "phantom4"]), (["registry", "models"], ["phantom4"])):
        assert main(["--db", db, *argv]) == 0
        out = capsys.readouterr().out
        assert max(len(line) for line in out.splitlines()) <= 80 and "…" not in out, out
        for word in whole:
            assert word in out, (argv, word, out)
        if argv == ["registry", "list"]:
            assert re.search(r"\b01[0-9A-F]{32}\b", out), out  # the 34-character session ID on one line


# --- waveform guidance ------------------------------------------------------------------------

def test_no_bundle_names_the_nearest_and_the_parameter_that_differs(tmp_path: Path, capsys) -> None:
    from signatures.classify.inference import NoModelError, find_bundle
    from signatures.radar import PRESETS, waveform_of

    paper = PRESETS["paper"]
    assert find_bundle(waveform_of(paper.config.replace(pri_s=4.403e-5, ramp_s=4.403e-5), 600, 80)).name == "paper"
    slower = paper.config.replace(pri_s=4.5e-5, ramp_s=4.5e-5)  # 2 %: beyond the 1e-3 tolerance
    with pytest.raises(NoModelError) as err:
        find_bundle(waveform_of(slower, 600, 80), "x.h5")
    text = str(err.value)
    assert text.startswith("PRI 4.5e-05 s here, 4.403046056615607e-05 s in bundle paper: no classifier"), text
    assert "nearest bundle paper differs in pri_s" in text and "pri_s 4.403046056615607e-05 there, 4.5e-05 here" \
        in text and "tolerance 0.001 relative" in text and "`authn models list --json`" in text, text
    flight = tmp_path / "cut.h5"
    assert main(["simulate", "--model", "m300", "--range", "500", "--chirps", "512", "--out", str(flight)]) == 0
    db = f"sqlite:///{tmp_path / 'r.sqlite3'}"
    assert main(["--db", db, "register", "--serial", M300, "--model", "m300"]) == 0
    capsys.readouterr()
    assert main(["--db", db, "check", str(flight), "--serial", M300]) == 2
    err_line = capsys.readouterr().err.strip()
    assert err_line.count("\n") == 0 and "nearest bundle paper differs in n_chirps 600 there, 512 here" in err_line


def test_models_list_json_prints_the_exact_waveform(capsys) -> None:
    from signatures.radar import PRESETS, WAVEFORM_FIELDS

    assert main(["models", "list", "--json"]) == 0
    docs = {d["name"]: d for d in json.loads(capsys.readouterr().out)}
    for name, pre in PRESETS.items():
        wf = docs[name]["waveform"]
        assert docs[name]["kind"] == "shipped" and docs[name]["error"] is None
        assert all(wf[f] == getattr(pre.config, f) for f in WAVEFORM_FIELDS)  # exact, not rounded
        assert (wf["n_chirps"], wf["n_samples"], wf["domain"]) == (pre.n_chirps, pre.n_samples, pre.domain)


def test_models_list_json_waveform_is_a_radar_config_file(tmp_path: Path, capsys) -> None:
    from signatures.radar import load_waveform

    assert main(["models", "list", "--json"]) == 0
    wf = json.loads(capsys.readouterr().out)[0]["waveform"]
    path = tmp_path / "paper.json"
    path.write_text(json.dumps({k: v for k, v in wf.items() if k not in ("description", "key")}))
    assert load_waveform(path).shipped


# --- JSON -------------------------------------------------------------------------------------

def test_json_errors_are_one_object_on_stdout(tmp_path: Path, capsys) -> None:
    db = f"sqlite:///{tmp_path / 'r.sqlite3'}"
    cases = [(["registry", "show", "NOSUCH", "--json"], 2), (["audit", "replay", "99", "--json"], 2),
             (["registry", "list", "--json", "--bogus"], 2), (["simulate", "--model", "m300", "--range", "500",
                                                               "--out", str(tmp_path / "x.txt"), "--json"], 2)]
    for argv, code in cases:
        capsys.readouterr()
        assert main(["--db", db, *argv]) == code, argv
        cap = capsys.readouterr()
        doc = json.loads(cap.out)
        assert set(doc) == {"error", "exit_code"} and doc["exit_code"] == code and doc["error"], (argv, cap)
        assert "error:" not in cap.err, (argv, cap.err)


def test_json_on_audit_simulate_and_demo(tmp_path: Path, capsys) -> None:
    """A single check is a track of one dwell: at the default targets one unsigned dwell is
    `inconclusive` (exit 4), audited and replayed as such."""
    db = f"sqlite:///{tmp_path / 'r.sqlite3'}"
    flight = tmp_path / "m300.h5"
    assert main(["simulate", "--model", "m300", "--range", "500", "--rid-serial", M300, "--out", str(flight),
                 "--json"]) == 0
    sim = json.loads(capsys.readouterr().out)
    assert sim["files"][0]["file"] == str(flight) and sim["shape"] == [600, 80] and sim["waveform"] == "paper"
    assert main(["--db", db, "register", "--serial", M300, "--model", "m300"]) == 0
    assert main(["--db", db, "check", str(flight)]) == 4
    capsys.readouterr()
    assert main(["--db", db, "audit", "verify", "--json"]) == 0
    v = json.loads(capsys.readouterr().out)
    assert v["ok"] is True and v["entries"] == 1 and len(v["tree_root"]) == 64 and v["first_bad_seq"] is None
    assert main(["--db", db, "audit", "replay", "1", "--json"]) == 0
    r = json.loads(capsys.readouterr().out)
    assert r["same"] is True and r["recorded"] == r["replayed"] == {"decision": "inconclusive",
                                                                    "reasons": ["radar-inconclusive"]}
    assert main(["--db", db, "demo", "--out", str(tmp_path / "demo"), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["ok"] is True and len(d["scenes"]) == 9 and all(s["decision"] == s["expected"] for s in d["scenes"])


# --- rough edges ------------------------------------------------------------------------------

def test_simulate_checks_the_extension_and_the_serial_like_check(tmp_path: Path, capsys) -> None:
    base = ["simulate", "--model", "m300", "--range", "500"]
    for argv, needle in (([*base, "--out", str(tmp_path / "x.txt")], "written as .h5 (HDF5) or .npz, not .txt"),
                         ([*base, "--rid-serial", "bad serial", "--out", str(tmp_path / "y.h5")],
                          "--rid-serial: 'bad serial' is not a UAS ID")):
        capsys.readouterr()
        assert main(argv) == 2, argv
        err = capsys.readouterr().err
        assert err.startswith("error: ") and err.count("\n") == 1 and needle in err, err
    assert not list(tmp_path.iterdir())


def test_registry_import_skip_existing_makes_a_re_import_idempotent(tmp_path: Path, capsys) -> None:
    db = f"sqlite:///{tmp_path / 'r.sqlite3'}"
    csv = tmp_path / "fleet.csv"
    csv.write_text(f"serial,model\n{M300},m300\n1581BDEM00000043,m600\n")
    assert main(["--db", db, "registry", "import", str(csv)]) == 0
    capsys.readouterr()
    assert main(["--db", db, "registry", "import", str(csv)]) == 2  # refused as before: nothing changes
    assert f"serial {M300}: already registered" in capsys.readouterr().err
    csv.write_text(csv.read_text() + "1581BDEM00000044,phantom4\n")
    assert main(["--db", db, "registry", "import", str(csv), "--skip-existing"]) == 0
    assert "imported 1 identities" in (out := capsys.readouterr().out) and "skipped 2 already registered" in out
    assert main(["--db", db, "registry", "import", str(csv), "--skip-existing"]) == 0
    assert "imported 0 identities" in capsys.readouterr().out
    assert main(["--db", db, "registry", "list"]) == 0
    assert len(capsys.readouterr().out.splitlines()) == 3


def test_a_port_held_by_another_program_gives_one_friendly_line(tmp_path: Path) -> None:
    """(A second `authn serve` on the port: tests/service/test_connection_limits.py; a bad --db
    scheme naming the supported ones: tests/registry/test_db_url.py.)"""
    import socket

    with socket.socket() as held:
        held.bind(("127.0.0.1", 0))
        held.listen()
        port = held.getsockname()[1]
        run = subprocess.run([sys.executable, "-m", "authn", "--db", f"sqlite:///{tmp_path / 'r.sqlite3'}", "serve",
                              "--port", str(port)], capture_output=True, text=True, timeout=120,
                             env={**os.environ, "COLUMNS": "80"})
    assert run.returncode == 3 and f"error: port {port} on 127.0.0.1 is in use" in run.stderr, run.stderr
    assert "Traceback" not in run.stderr and "OSError" not in run.stderr


# --- CW files and unmeasured values -----------------------------------------------------------

def test_cw_files_inspect_plot_and_features_say_n_a(tmp_path: Path, capsys) -> None:
    cw, fm = tmp_path / "cw.h5", tmp_path / "paper.h5"
    assert main(["simulate", "--model", "m300", "--range", "500", "--domain", "cw", "--out", str(cw)]) == 0
    assert main(["simulate", "--model", "m300", "--range", "500", "--out", str(fm)]) == 0
    capsys.readouterr()
    assert main(["inspect", str(cw)]) == 0
    rows = dict(line.split("\t") for line in capsys.readouterr().out.splitlines())
    assert rows["domain"] == "cw" and rows["bandwidth"] == rows["range resolution"] == "n/a (CW)", rows
    assert main(["inspect", str(cw), "--json"]) == 0
    derived = json.loads(capsys.readouterr().out)["derived"]
    assert derived["range_resolution_m"] is None and derived["range_window_m"] is None and derived["prf_hz"] > 0
    assert main(["plot", str(cw), "--out", str(tmp_path / "png")]) == 0
    assert "rd_map.png: skipped" in capsys.readouterr().err
    assert not (tmp_path / "png" / "rd_map.png").exists() and (tmp_path / "png" / "spectrogram.png").is_file()
    assert main(["features", "show", str(cw), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["features"]["range_m"] is None and "range_m" in doc["unmeasured"]
    assert main(["features", "show", str(fm)]) == 0  # paper: the blade tips alias
    line = next(ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("blade_length_m "))
    assert "n/a" in line and "blade tips alias" in line, line
