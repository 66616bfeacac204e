"""The append-only triggers an audit table gets (refuse UPDATE and DELETE, and TRUNCATE on
PostgreSQL): the DDL for one dialect, and the create/drop steps every audit-table migration
(0001 to 0005) takes."""

from __future__ import annotations

from typing import Any


def append_only(table: str, dialect: str) -> list[str]:
    if dialect == "sqlite":
        return [f"CREATE TRIGGER {table}_no_{op_} BEFORE {op_.upper()} ON {table} "
                f"BEGIN SELECT RAISE(ABORT, '{table} is append-only'); END" for op_ in ("update", "delete")]
    if dialect != "postgresql":
        return []
    fn = f"{table}_append_only"
    return [f"CREATE FUNCTION {fn}() RETURNS trigger LANGUAGE plpgsql AS $$ "
            f"BEGIN RAISE EXCEPTION '{table} is append-only'; END; $$",
            f"CREATE TRIGGER {table}_no_update BEFORE UPDATE ON {table} FOR EACH ROW EXECUTE FUNCTION {fn}()",
            f"CREATE TRIGGER {table}_no_delete BEFORE DELETE ON {table} FOR EACH ROW EXECUTE FUNCTION {fn}()",
            f"CREATE TRIGGER {table}_no_truncate BEFORE TRUNCATE ON {table} "
            f"FOR EACH STATEMENT EXECUTE FUNCTION {fn}()"]


def make_append_only(op: Any, table: str) -> None:
    """Give `table` its append-only triggers (alembic's `op`, inside a migration)."""
    for ddl in append_only(table, op.get_bind().dialect.name):
        op.execute(ddl)


def create_append_only(op: Any, table: str, *elements: Any) -> None:
    """`op.create_table(table, *elements)`, append-only from its first row."""
    op.create_table(table, *elements)
    make_append_only(op, table)


def replace_in_table(op: Any, table: str, changes: list[tuple[str, str]], constraint: str | None = None) -> None:
    """Rewrite an append-only table's definition: on SQLite the table is rebuilt from its DDL with each
    (old, new) text replaced (its rows copied, its indexes and triggers made again; refused where an
    old text is not in the DDL); on PostgreSQL `constraint` (a CHECK, named) is dropped and added
    with the last change's new text (column changes are the caller's ALTER)."""
    import sqlalchemy as sa

    bind = op.get_bind()
    if bind.dialect.name == "postgresql":
        if constraint is not None:
            op.execute(f"ALTER TABLE {table} DROP CONSTRAINT {constraint}")
            op.execute(f"ALTER TABLE {table} ADD CONSTRAINT {constraint} CHECK ({changes[-1][1]})")
        return
    if bind.dialect.name != "sqlite":
        return
    (ddl,) = bind.execute(sa.text("SELECT sql FROM sqlite_master WHERE type = 'table' AND name = :t"),
                          {"t": table}).one()
    for old, new in changes:
        if old not in ddl:
            raise RuntimeError(f"{table}'s definition lacks {old!r}; refusing to rebuild the table")
        ddl = ddl.replace(old, new)
    indexes = [r[0] for r in bind.execute(sa.text(
        "SELECT sql FROM sqlite_master WHERE type = 'index' AND tbl_name = :t AND sql IS NOT NULL"), {"t": table})]
    op.execute(ddl.replace(table, f"{table}_rebuilt", 1))
    op.execute(f"INSERT INTO {table}_rebuilt SELECT * FROM {table}")
    op.execute(f"DROP TABLE {table}")  # its triggers go with it; DROP fires no DELETE trigger
    op.execute(f"ALTER TABLE {table}_rebuilt RENAME TO {table}")
    for sql in indexes:
        op.execute(sql)
    make_append_only(op, table)


def drop_append_only(op: Any, table: str) -> None:
    """Drop an append-only table: its triggers go with it, its PostgreSQL trigger function not."""
    op.drop_table(table)
    if op.get_bind().dialect.name == "postgresql":
        op.execute(f"DROP FUNCTION IF EXISTS {table}_append_only()")
