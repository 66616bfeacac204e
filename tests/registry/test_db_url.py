"""`--db`: a SQLite file is never created in a directory that does not exist (a typo would
otherwise become an empty registry, every check `unregistered`) unless on purpose with
`authn db upgrade --create`; a new database file is announced on stderr; only sqlite and
postgresql URLs are accepted, by name."""

from __future__ import annotations

import pytest

from authn.cli import main

NOTICE = "authn: created new database "


def _run(capsys, *args: str) -> tuple[int, str, str]:
    code = main(list(args))
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.parametrize("command", [["registry", "list"], ["audit", "list"], ["db", "upgrade"],
                                     ["register", "--serial", "1581F5FJD12345678901", "--model", "m300"]])
def test_missing_directory_is_bad_input_and_nothing_is_created(capsys, tmp_path, command):
    missing = tmp_path / "no" / "such" / "dir"
    code, out, err = _run(capsys, "--db", f"sqlite:///{missing / 'x.db'}", *command)
    assert code == 2, err
    assert err == (f"error: --db: directory {missing} does not exist; create the database on purpose "
                   "with `authn db upgrade --create`\n")
    assert not (tmp_path / "no").exists()


def test_check_with_missing_directory_exits_2_and_creates_nothing(capsys, tmp_path):
    bad = tmp_path / "flight.h5"
    bad.write_text("not hdf5")
    code, _, err = _run(capsys, "--db", f"sqlite:///{tmp_path / 'typo' / 'r.db'}", "check", str(bad),
                        "--serial", "1581F5FJD12345678901")
    assert code == 2 and err.startswith("error: ") and err.count("\n") == 1, err
    assert not (tmp_path / "typo").exists()


def test_db_upgrade_create_makes_the_directory_and_says_so_once(capsys, tmp_path):
    url = f"sqlite:///{tmp_path / 'srv' / 'authn' / 'registry.sqlite3'}"
    code, out, err = _run(capsys, "--db", url, "db", "upgrade", "--create")
    assert code == 0 and "at revision" in out
    assert err == f"{NOTICE}{url} (empty registry)\n"
    assert (tmp_path / "srv" / "authn" / "registry.sqlite3").is_file()
    for command in (["registry", "list", "--json"], ["audit", "list", "--json"], ["db", "upgrade"]):
        code, _, err = _run(capsys, "--db", url, *command)
        assert code == 0 and err == "", (command, err)


@pytest.mark.parametrize("command", [["registry", "list", "--json"], ["audit", "list", "--json"], ["db", "upgrade"]])
def test_new_file_in_existing_directory_is_announced_once(capsys, tmp_path, command):
    url = f"sqlite:///{tmp_path / 'fresh.sqlite3'}"
    code, _, err = _run(capsys, "--db", url, *command)
    assert code == 0 and err == f"{NOTICE}{url} (empty registry)\n"
    code, _, err = _run(capsys, "--db", url, *command)
    assert code == 0 and err == ""


def test_environment_variable_follows_the_same_rule(capsys, tmp_path, monkeypatch):
    monkeypatch.setenv("AUTHN_DATABASE_URL", f"sqlite:///{tmp_path / 'nope' / 'r.db'}")
    code, _, err = _run(capsys, "registry", "list")
    assert code == 2 and "does not exist" in err and not (tmp_path / "nope").exists()


def test_default_database_is_created_on_first_use_with_a_notice(capsys, tmp_path, monkeypatch):
    """No --db: the user data directory (made if missing, as on a fresh machine) holds it."""
    monkeypatch.delenv("AUTHN_DATABASE_URL", raising=False)
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "home" / "share"))
    from registry.urls import default_url

    url = default_url()
    assert url.startswith(f"sqlite:///{tmp_path}")
    code, _, err = _run(capsys, "registry", "list", "--json")
    assert code == 0 and err == f"{NOTICE}{url} (empty registry)\n"
    assert list((tmp_path / "home").rglob("registry.sqlite3"))
    from registry.db import dispose_engines

    dispose_engines()


@pytest.mark.parametrize("url, shown", [
    ("foo://bar", "scheme 'foo' is not supported"),
    ("mysql://user:hunter2@db/authn", "'mysql://user:***@db/authn'"),
    ("/var/lib/authn/registry.sqlite3", "is not a URL"),
    ("nonsense://", "scheme 'nonsense' is not supported"),
])
@pytest.mark.parametrize("command", [["registry", "list"], ["audit", "list"], ["db", "upgrade"]])
def test_unsupported_scheme_names_the_supported_ones(capsys, url, shown, command):
    code, _, err = _run(capsys, "--db", url, *command)
    assert code == 2 and err.startswith("error: --db ") and err.count("\n") == 1, err
    assert shown in err and "supported: sqlite, postgresql" in err
    assert "plugin" not in err and "hunter2" not in err


def test_library_engine_refuses_a_missing_directory_unless_create(tmp_path):
    from registry.db import create_db_engine
    from registry.errors import RegistryError

    url = f"sqlite:///{tmp_path / 'a' / 'b.db'}"
    with pytest.raises(RegistryError, match="does not exist"):
        create_db_engine(url)
    create_db_engine(url, create=True).dispose()
    assert (tmp_path / "a").is_dir()
