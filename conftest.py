"""Every pytest run in this repository (tests/, benchmarks/, lab/, any file alone) runs with a
temporary HOME: before anything computes a default path (this module is imported before any
test module), HOME, the XDG base directories, matplotlib's config folder and every AUTHN_*
path that defaults into the user data dir point into one temporary folder, removed at the end.
A test, a benchmark, a CLI subprocess (it inherits os.environ) or platformdirs can then never
write a log key, signed heads or a registry into the developer's real ~/.local/share/authn
(tests/test_test_isolation.py proves it). Here, at the root, because pytest loads the
conftest.py files of the rootdir and of each argument's folders only: tests/conftest.py is
not loaded by `pytest benchmarks/...`."""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

#: The environment variable naming the session's temporary folder (a child process reuses it).
SESSION_ROOT = "AUTHN_TEST_SESSION_ROOT"


def _pin_user_dirs() -> Path:
    """Point HOME, XDG_* and the authn paths at a fresh temporary folder (see the docstring).
    A PostgreSQL password file of the real HOME stays usable through PGPASSFILE. Once per
    process tree: a process that inherits a pinned folder keeps it."""
    if os.environ.get(SESSION_ROOT) and Path(os.environ[SESSION_ROOT]).is_dir():
        return Path(os.environ[SESSION_ROOT])
    root = Path(tempfile.mkdtemp(prefix="authn-test-home-"))
    os.environ[SESSION_ROOT] = str(root)
    real_pgpass = Path(os.path.expanduser("~/.pgpass"))
    if "PGPASSFILE" not in os.environ and real_pgpass.is_file():
        os.environ["PGPASSFILE"] = str(real_pgpass)
    home = root / "home"
    dirs = {"HOME": home, "XDG_DATA_HOME": home / ".local" / "share", "XDG_CONFIG_HOME": home / ".config",
            "XDG_CACHE_HOME": home / ".cache", "XDG_STATE_HOME": home / ".local" / "state",
            "XDG_RUNTIME_DIR": root / "run", "MPLCONFIGDIR": root / "matplotlib"}
    for name, path in dirs.items():
        path.mkdir(parents=True, exist_ok=True)
        os.environ[name] = str(path)
    os.chmod(dirs["XDG_RUNTIME_DIR"], 0o700)
    data = dirs["XDG_DATA_HOME"] / "authn-tests"
    data.mkdir()
    os.environ["AUTHN_LOG_KEY"] = str(data / "audit-log-key.pem")
    os.environ["AUTHN_AUDIT_STH_LOG"] = str(data / "audit-sth.jsonl")
    os.environ["AUTHN_DATABASE_URL"] = f"sqlite:///{data / 'registry.sqlite3'}"
    os.environ["AUTHN_MODELS_DIR"] = str(data / "user-models")
    os.environ.setdefault("AUTHN_CACHE_DIR", str(dirs["XDG_CACHE_HOME"] / "authn-tests-datasets"))
    return root


#: The session's temporary HOME and friends; set at import, before any test module is collected.
PINNED_ROOT = _pin_user_dirs()


def _hypothesis_profiles() -> None:
    """`HYPOTHESIS_PROFILE=ci` (set by .ci/run) draws every property test's examples from a seed
    fixed per test, so CI judges the same examples on every run; elsewhere they are random, and a
    failure found prints the example to pin with `@example`."""
    from hypothesis import settings

    settings.register_profile("ci", derandomize=True, print_blob=True)
    settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "default"))


_hypothesis_profiles()


def pytest_unconfigure(config) -> None:
    shutil.rmtree(PINNED_ROOT, ignore_errors=True)
