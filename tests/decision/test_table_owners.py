"""One owner per table: registry/models.py defines every table (and Alembic creates it from
there); the raw SQL of the per-check DB-API path (the authn.audit package writes the audit tables,
registry/dbapi.py reads identities) names only columns the models define, so the two cannot
drift apart unnoticed."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

import authn.audit
import authn.audit._internal.headrows
import authn.audit._internal.rows
import registry.dbapi
from registry.models import Base

ROOT = Path(__file__).resolve().parents[2]
INSERT = re.compile(r"INSERT INTO (\w+) \(([^)]*)\)")
SELECT = re.compile(r"SELECT ([\w, ]+?) FROM (\w+)")


def _sql_of(module) -> str:
    path = Path(module.__file__)
    files = sorted(path.parent.rglob("*.py")) if path.name == "__init__.py" else [path]
    text = re.sub(r'"\s*\n\s*f?"', "", "\n".join(p.read_text() for p in files))  # join implicit concatenations
    return text.replace("{COLUMNS}", authn.audit._internal.rows.COLUMNS).replace(
        "{HEAD_COLUMNS}", authn.audit._internal.headrows.HEAD_COLUMNS)


@pytest.mark.parametrize("module", [authn.audit, registry.dbapi], ids=["authn.audit", "registry.dbapi"])
def test_raw_sql_names_only_model_columns(module) -> None:
    text = _sql_of(module)
    tables = Base.metadata.tables
    uses = [(t, cols) for t, cols in INSERT.findall(text)] + [(t, cols) for cols, t in SELECT.findall(text)]
    assert uses, "the module's SQL was not found"
    for table, cols in uses:
        if table == "alembic_version":
            continue
        assert table in tables, f"{module.__name__} uses table {table} that registry/models.py does not define"
        names = {c.strip() for c in cols.split(",")} - {"COUNT(*)", "MAX(id)"}
        unknown = names - set(tables[table].columns.keys())
        assert not unknown, f"{module.__name__}: {table} has no columns {sorted(unknown)}"


def test_audit_tables_have_a_single_writer() -> None:
    """Only the authn.audit package (and the migrations) writes the audit tables."""
    writers = set()
    for path in list((ROOT / "authn").rglob("*.py")) + list((ROOT / "registry").rglob("*.py")):
        if "migrations" in path.parts:
            continue
        if re.search(r"INSERT INTO audit_(log|policies|tree_heads|batches|log_meta)", path.read_text()):
            writers.add("/".join(path.relative_to(ROOT).parts[:2]))  # the package, _internal included
    assert writers == {"authn/audit"}
