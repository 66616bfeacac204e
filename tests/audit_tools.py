"""What the tamper tests do to an audit log: lift the append-only guards, as a database
writer with full rights could, so a test can rewrite rows the way an attacker would."""

from __future__ import annotations


def drop_triggers(url: str) -> None:
    """Drop every trigger (SQLite), or disable the audit tables' triggers (PostgreSQL)."""
    from registry.db import get_engine

    engine = get_engine(url)
    with engine.begin() as conn:
        if engine.dialect.name == "sqlite":
            for (name,) in conn.exec_driver_sql("SELECT name FROM sqlite_master WHERE type='trigger'").all():
                conn.exec_driver_sql(f"DROP TRIGGER {name}")
        else:
            for table in ("audit_log", "audit_tree_heads", "audit_policies", "audit_log_meta"):
                conn.exec_driver_sql(f"ALTER TABLE {table} DISABLE TRIGGER ALL")
