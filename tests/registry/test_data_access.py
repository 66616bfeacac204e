"""One runtime data-access layer (docs/architecture.md, one way per job): every query runs
through `registry.dbapi` (DB-API on sqlite3 / psycopg); SQLAlchemy is imported only where
Alembic needs it: the schema Alembic compares against (`registry.models`), the migrations
(`registry.migrations`) and Alembic's engine (`registry.db`, handed a database to migrate)."""

from __future__ import annotations

import ast
import os
import subprocess
import sys
from pathlib import Path

from tests.test_architecture import PRODUCT, ROOT, _imports_in, _modules

#: the only product modules that may import SQLAlchemy, and why
ALEMBIC_ONLY = {
    "registry.models": "the schema Alembic autogenerates and compares against",
    "registry.db": "Alembic's engine and the migration lock",
}


def _runtime_tree(tree: ast.Module) -> ast.Module:
    """`tree` without its `if TYPE_CHECKING:` blocks (imports for the type checker only)."""
    class Strip(ast.NodeTransformer):
        def visit_If(self, node: ast.If) -> ast.AST | None:
            test = node.test
            name = test.id if isinstance(test, ast.Name) else test.attr if isinstance(test, ast.Attribute) else ""
            return None if name == "TYPE_CHECKING" else self.generic_visit(node)

    return Strip().visit(tree)


def _sqlalchemy_importers(sources: dict[str, str]) -> list[str]:
    out = []
    for module, source in sources.items():
        if module in ALEMBIC_ONLY or module == "registry.migrations" or module.startswith("registry.migrations."):
            continue
        names = _imports_in(_runtime_tree(ast.parse(source)), module_level=False)
        if any(n == "sqlalchemy" or n.startswith("sqlalchemy.") for n in names):
            out.append(module)
    return sorted(out)


def _product_sources() -> dict[str, str]:
    return {m: p.read_text() for m, p in _modules().items() if m.split(".")[0] in PRODUCT}


def test_only_alembic_modules_import_sqlalchemy() -> None:
    """No product module outside the migrations, the schema and Alembic's engine imports
    SQLAlchemy, at module level or inside a function."""
    assert _sqlalchemy_importers(_product_sources()) == []


def test_the_check_finds_a_planted_sqlalchemy_import() -> None:
    planted = {
        "registry.store": "def f():\n    from sqlalchemy import select\n",
        "authn.service.keys": "import sqlalchemy.orm\n",
        "authn.typed": "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from sqlalchemy import Engine\n",
        "registry.migrations.env": "from sqlalchemy import pool\n",
        "registry.models": "from sqlalchemy import Integer\n",
    }
    assert _sqlalchemy_importers(planted) == ["authn.service.keys", "registry.store"]


def test_registry_and_api_key_work_on_a_current_database_never_import_sqlalchemy(db_url: str) -> None:
    """Register, revoke, list, import, export and the API keys' create / list / revoke, in a
    fresh process on a migrated database: SQLAlchemy is never imported."""
    from registry.db import get_engine

    get_engine(db_url)  # migrate first: migrating is SQLAlchemy's one job
    script = """
import sys
from authn.service.keys import create_key, list_keys, revoke_key
from registry.dbapi import transaction
from registry.store import (NewIdentity, export_json, get_identity, import_json, list_identities,
                            register_identity, revoke_identity)
url = sys.argv[1]
with transaction(url) as db:
    register_identity(db, NewIdentity(serial="1581F5FJD12345678901", model="m300"))
    revoke_identity(db, "1581F5FJD12345678901", "lost")
    doc = export_json(db)
with transaction(url) as db:
    assert list_identities(db, "revoked")[0].notes == "revoked: lost"
    import_json(db, doc.replace("1581F5FJD12345678901", "1581F5FJD12345678902"))
    assert get_identity(db, "1581F5FJD12345678902").status == "revoked"
info, _ = create_key(url, "operator", "ci")
revoke_key(url, info.id)
assert list_keys(url)[0].revoked_at is not None
assert "sqlalchemy" not in sys.modules, sorted(m for m in sys.modules if m.startswith("sqlalchemy"))[:3]
print("ok")
"""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    done = subprocess.run([sys.executable, "-c", script, db_url], capture_output=True, text=True, env=env,
                          cwd=Path(ROOT), timeout=120)
    assert done.returncode == 0 and done.stdout.strip() == "ok", done.stderr[-2000:]


def test_sqlite_times_keep_four_digit_years(tmp_path: Path) -> None:
    """SQLite stores naive UTC text compared as text (`valid_until > valid_from`): year 1 is
    `0001`, as SQLAlchemy wrote it, not strftime's `1`, and it reads back as written."""
    from datetime import datetime, timedelta, timezone

    from registry.dbapi import Database

    db = Database(f"sqlite:///{tmp_path / 'r.sqlite3'}")
    early = datetime(1, 1, 2, 3, 4, 5, 6, tzinfo=timezone(timedelta(hours=2)))
    stored = db.to_db_time(early)
    assert stored == "0001-01-02 01:04:05.000006"
    assert Database.from_db_time(stored) == early


def test_the_stores_columns_are_the_models() -> None:
    """The registry store's and the API keys' SQL name the columns the schema defines (the
    store builds its statements from these tuples)."""
    from authn.service import keys
    from registry import store
    from registry.models import Base

    tables = Base.metadata.tables
    assert set(store._PROFILE_COLUMNS) == set(tables["model_profiles"].columns.keys())
    assert set(store._IDENTITY_COLUMNS) == set(tables["identities"].columns.keys()) - {"id"}
    assert {c.strip() for c in keys._COLUMNS.split(",")} == set(tables["api_keys"].columns.keys()) - {"key_hash"}


def test_a_database_found_current_is_not_asked_its_version_again(tmp_path: Path, monkeypatch) -> None:
    """The version query runs once per database and process, and again for a file this process
    creates anew (a deleted database is migrated again, not trusted from memory)."""
    from registry import dbapi

    asked: list[str] = []
    real = dbapi.Database._current

    def counted(self: dbapi.Database, conn: object) -> bool:
        asked.append(self.url)
        return real(self, conn)

    monkeypatch.setattr(dbapi.Database, "_current", counted)
    url = f"sqlite:///{tmp_path / 'reg.sqlite3'}"
    for _ in range(3):
        with dbapi.transaction(url) as db:
            assert db.fetch("SELECT count(*) FROM identities") == [(0,)]
    assert len(asked) == 1
    (tmp_path / "reg.sqlite3").unlink()
    with dbapi.transaction(url) as db:
        assert db.fetch("SELECT count(*) FROM identities") == [(0,)]
    assert len(asked) == 2
