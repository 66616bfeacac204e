"""Shared fixtures: a fresh database per test, on SQLite always and on PostgreSQL too
when AUTHN_TEST_POSTGRES_URL points at a server; the audit log key and user models per
session; the benchmark scripts as modules. The temporary HOME every run has is the root
conftest.py's."""

from __future__ import annotations

import importlib.util
import os
import uuid
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from types import ModuleType

import pytest


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
