"""Fixtures of the service tests: a database with the example identities and API keys, a
running server on it, and simulated returns."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import pytest

from tests.service.server import M300, M600, Server, flight, server_env, start


@dataclass
class Keys:
    admin: str
    operator: str
    admin_id: int
    operator_id: int


def make_keys(db_url: str) -> Keys:
    from authn.service.keys import create_key

    admin, admin_token = create_key(db_url, "admin", "test-admin")
    operator, operator_token = create_key(db_url, "operator", "test-operator")
    return Keys(admin_token, operator_token, admin.id, operator.id)


@pytest.fixture(scope="session")
def keys_dir(tmp_path_factory) -> Path:
    """The audit log key folder the root conftest gives every test (same path)."""
    path = tmp_path_factory.getbasetemp() / "audit-keys"
    path.mkdir(exist_ok=True)
    return path


@pytest.fixture(scope="module")
def returns(tmp_path_factory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("returns")
    return {"genuine": flight(root, "genuine", "m300", M300),
            "type": flight(root, "type", "phantom4", M600)}


@pytest.fixture(scope="module")
def sqlite_db(tmp_path_factory) -> str:
    from authn.demo import register_examples

    url = f"sqlite:///{tmp_path_factory.mktemp('svc') / 'authn.sqlite3'}"
    register_examples(url)
    return url


@pytest.fixture(scope="module")
def pg_db():
    """A fresh PostgreSQL database with the example identities (skipped without a server)."""
    from authn.demo import register_examples
    from tests.conftest import fresh_pg_database

    with fresh_pg_database("authn_svc") as url:
        register_examples(url)
        yield url


@pytest.fixture(scope="module")
def keys(sqlite_db) -> Keys:
    return make_keys(sqlite_db)


@pytest.fixture(scope="module")
def server(sqlite_db, keys, keys_dir, tmp_path_factory) -> Server:
    """One server (1 worker, 4 MiB upload limit, 3 s upload timeout) on the SQLite database."""
    srv = start(sqlite_db, tmp_path_factory.mktemp("log") / "serve.log", server_env(keys_dir), "--max-upload-mib", "4",
                "--upload-timeout-s", "3", "--body-timeout-s", "2")
    yield srv
    log = srv.stop()
    assert "Traceback" not in log, log[-3000:]
    assert srv.proc.returncode == 0, log[-3000:]  # SIGTERM is a clean stop
