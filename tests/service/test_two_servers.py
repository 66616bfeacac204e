"""Several servers on one database keep one audit chain: concurrent checks through two
`authn serve` processes (one of them with two workers), then `audit verify` holds with
exactly the entries made (none lost, none forked). On SQLite always, on PostgreSQL when
AUTHN_TEST_POSTGRES_URL is set."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import pytest

from authn.cli import main
from tests.service.conftest import make_keys
from tests.service.server import server_env, start

CLIENTS, CHECKS_EACH = 4, 8


@pytest.fixture(params=["sqlite", "postgresql"])
def database(request) -> str:
    return request.getfixturevalue("sqlite_db" if request.param == "sqlite" else "pg_db")


def _count(db_url: str) -> int:
    from registry.dbapi import Database

    return int(Database(db_url).fetch("SELECT COUNT(*) FROM audit_log")[0][0])


def test_two_servers_one_chain(database, returns, keys_dir, tmp_path, capsys) -> None:
    token = make_keys(database).operator
    env = server_env(keys_dir)
    before = _count(database)
    servers = [start(database, tmp_path / "a.log", env, "--workers", "2"), start(database, tmp_path / "b.log", env)]
    body = returns["genuine"].read_bytes()

    def client(i: int) -> list[int]:
        with servers[i % 2].client(token) as c:
            return [c.post("/v1/checks", files={"file": ("g.h5", body, "application/x-hdf5")}).status_code
                    for _ in range(CHECKS_EACH)]

    try:
        with ThreadPoolExecutor(CLIENTS) as pool:
            statuses = [s for part in pool.map(client, range(CLIENTS)) for s in part]
    finally:
        logs = [s.stop() for s in servers]
    assert statuses == [200] * CLIENTS * CHECKS_EACH
    assert all("Traceback" not in log for log in logs)
    assert _count(database) - before == CLIENTS * CHECKS_EACH
    capsys.readouterr()
    assert main(["--db", database, "audit", "verify"]) == 0
    assert f"ok: {before + CLIENTS * CHECKS_EACH} entries" in capsys.readouterr().out
