"""Alembic migration environment for the registry and audit schema."""

#: The newest revision in versions/. Lets a process confirm its database is current
#: with one SELECT instead of importing Alembic (~0.2 s); a test keeps it equal to
#: Alembic's own head.
HEAD_REVISION = "0002"
