"""Alembic migration environment for the registry and audit schema."""
