"""A local Dask cluster of 2 worker processes and an archive of paper-preset returns with the
bench's mix of claims, shared by the module's tests (each cluster start costs seconds)."""

from __future__ import annotations

from pathlib import Path

import pytest

pytest.importorskip("distributed", reason="the cluster extra (pip install '.[cluster]')")


@pytest.fixture(scope="module")
def archive(tmp_path_factory) -> list[Path]:
    """40 recorded returns: genuine claims, type and position spoofs, unregistered, revoked."""
    from lab.bench.perf import _files, _mixed_serial

    folder = tmp_path_factory.mktemp("archive")
    return _files(folder, "paper", 40, 7, _mixed_serial)


@pytest.fixture(scope="module")
def client(tmp_path_factory):
    """Workers spawned with the session's audit log key (the autouse fixture that sets it runs
    per test, after this module-scoped one)."""
    from authn.cluster.engine import connect

    keys = tmp_path_factory.getbasetemp() / "audit-keys"
    keys.mkdir(exist_ok=True)
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("AUTHN_LOG_KEY", str(keys / "audit-log-key.pem"))
        mp.setenv("AUTHN_AUDIT_STH_LOG", str(keys / "audit-sth.jsonl"))
        with connect("local", workers=2) as c:
            yield c


@pytest.fixture(params=["sqlite", "postgresql"])
def registry_url(request, tmp_path):
    """A registry holding the bench identities, on SQLite and (with a server) PostgreSQL."""
    from lab.bench.decisions import register_identities
    from registry.db import dispose_engines
    from tests.conftest import fresh_pg_database

    if request.param == "sqlite":
        url = f"sqlite:///{tmp_path / 'registry.sqlite3'}"
        register_identities(url)
        yield url
        dispose_engines()
        return
    with fresh_pg_database("authn_cluster") as url:
        register_identities(url)
        yield url
