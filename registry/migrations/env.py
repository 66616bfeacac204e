"""Alembic environment: runs on the connection the caller passes in.

`registry.db.alembic_config(conn)` builds the configuration in code; SQLite
uses batch mode because it cannot ALTER most constraints in place.
"""

from alembic import context

from registry.models import Base

connection = context.config.attributes.get("connection")
if connection is None:
    raise RuntimeError("run migrations through registry.db (authn db upgrade)")

context.configure(
    connection=connection,
    target_metadata=Base.metadata,
    render_as_batch=connection.dialect.name == "sqlite",
    compare_type=True,
)
with context.begin_transaction():
    context.run_migrations()
