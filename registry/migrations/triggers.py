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


def drop_append_only(op: Any, table: str) -> None:
    """Drop an append-only table: its triggers go with it, its PostgreSQL trigger function not."""
    op.drop_table(table)
    if op.get_bind().dialect.name == "postgresql":
        op.execute(f"DROP FUNCTION IF EXISTS {table}_append_only()")
