"""Shared fixtures: a fresh database per test, on SQLite always and on PostgreSQL too
when AUTHN_TEST_POSTGRES_URL points at a server; the benchmark scripts as modules.

The whole session runs with a temporary HOME: before anything computes a default path
(this module is imported before any test module), HOME, the XDG base directories,
matplotlib's config folder and every AUTHN_* path that defaults into the user data dir
point into one temporary folder, removed at the end. A test, a CLI subprocess (it inherits
os.environ) or platformdirs can then never write a log key, signed heads or a registry into
the developer's real ~/.local/share/authn (tests/test_test_isolation.py proves it)."""

from __future__ import annotations

import importlib.util
import os
import shutil
import tempfile
import uuid
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from types import ModuleType

import pytest


_SESSION_ROOT = "AUTHN_TEST_SESSION_ROOT"


def _pin_user_dirs() -> Path:
    """Point HOME, XDG_* and the authn paths at a fresh temporary folder (see the docstring).
    A PostgreSQL password file of the real HOME stays usable through PGPASSFILE. Once per
    process: `from tests.conftest import ...` (tests/service) imports this file a second time."""
    if os.environ.get(_SESSION_ROOT) and Path(os.environ[_SESSION_ROOT]).is_dir():
        return Path(os.environ[_SESSION_ROOT])
    root = Path(tempfile.mkdtemp(prefix="authn-test-home-"))
    os.environ[_SESSION_ROOT] = str(root)
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


def pytest_unconfigure(config) -> None:
    shutil.rmtree(PINNED_ROOT, ignore_errors=True)


def pytest_terminal_summary(terminalreporter, exitstatus, config) -> None:
    """What was skipped and why, one line per reason with its count (pytest's own -rs lists
    every location: a hundred lines when the PostgreSQL cases skip)."""
    from collections import Counter

    reasons: Counter[str] = Counter()
    for report in terminalreporter.stats.get("skipped", []):
        if isinstance(report.longrepr, tuple):
            reasons[str(report.longrepr[2]).removeprefix("Skipped: ")] += 1
    if reasons:
        terminalreporter.section("skipped, by reason")
        for reason, n in reasons.most_common():
            terminalreporter.write_line(f"{n:5d}  {reason}")

PG_URL = os.environ.get("AUTHN_TEST_POSTGRES_URL")
#: PostgreSQL cases are always collected; without a server they show as skipped, with the reason.
BACKENDS = ["sqlite", "postgresql"]


def _pg_admin():
    from sqlalchemy import create_engine

    from registry.db import resolve_url

    return create_engine(resolve_url(PG_URL), isolation_level="AUTOCOMMIT")


@contextmanager
def fresh_pg_database(prefix: str) -> Iterator[str]:
    """URL of a new empty PostgreSQL database (skips the test without a server), dropped after."""
    if not PG_URL:
        pytest.skip("PostgreSQL: set AUTHN_TEST_POSTGRES_URL to a server (.ci/run starts one)")
    from sqlalchemy.engine import make_url

    from registry.db import dispose_engines, resolve_url

    name = f"{prefix}_{uuid.uuid4().hex[:12]}"
    admin = _pg_admin()
    with admin.connect() as conn:
        conn.exec_driver_sql(f'CREATE DATABASE "{name}"')
    try:
        yield make_url(resolve_url(PG_URL)).set(database=name).render_as_string(hide_password=False)
    finally:
        dispose_engines()
        with admin.connect() as conn:
            conn.exec_driver_sql(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')
        admin.dispose()


@pytest.fixture(params=BACKENDS, ids=BACKENDS)
def db_url(request, tmp_path):
    """URL of an empty database (never migrated yet)."""
    from registry.db import dispose_engines

    if request.param == "sqlite":
        yield f"sqlite:///{tmp_path / 'registry.sqlite3'}"
        dispose_engines()
        return
    with fresh_pg_database("authn_test") as url:
        yield url


@pytest.fixture
def session(db_url):
    """A session on a migrated database; the test commits what it wants kept."""
    from sqlalchemy.orm import Session

    from registry.db import get_engine

    with Session(get_engine(db_url), expire_on_commit=False) as s:
        yield s


@pytest.fixture(autouse=True)
def _audit_log_key(tmp_path_factory, monkeypatch):
    """The audit log key and its signed-tree-head file live in a per-session temporary
    directory, never in the user's data directory."""
    keys = tmp_path_factory.getbasetemp() / "audit-keys"
    keys.mkdir(exist_ok=True)
    monkeypatch.setenv("AUTHN_LOG_KEY", str(keys / "audit-log-key.pem"))
    monkeypatch.setenv("AUTHN_AUDIT_STH_LOG", str(keys / "audit-sth.jsonl"))


_MODELS_DIR_AT_START = os.environ.get("AUTHN_MODELS_DIR")


@pytest.fixture(autouse=True)
def _no_user_models(tmp_path_factory, monkeypatch):
    """User model bundles (`authn models train --like`) come from an empty per-session folder,
    so a developer's own bundles never change which waveforms have a classifier in a test.
    A module fixture that set its own folder keeps it."""
    if os.environ.get("AUTHN_MODELS_DIR") != _MODELS_DIR_AT_START:
        return
    models = tmp_path_factory.getbasetemp() / "user-models"
    models.mkdir(exist_ok=True)
    monkeypatch.setenv("AUTHN_MODELS_DIR", str(models))


@pytest.fixture(scope="session")
def benchmark_script() -> Callable[[str], ModuleType]:
    """Loads `benchmarks/NAME.py` as a module (the scripts are not a package)."""
    def load(name: str) -> ModuleType:
        path = Path(__file__).resolve().parents[1] / "benchmarks" / f"{name}.py"
        spec = importlib.util.spec_from_file_location(name, path)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        return module
    return load
