"""Declared identities: what the registry holds and how it is read and written.

- `dbapi`: the one data-access layer, DB-API on the driver itself (every query of the
  product). `store`: registry queries and changes, import/export. `urls`: which database.
- `models`: the SQLAlchemy 2 schema of every table (registry and audit); Alembic
  (`registry/migrations/`) creates it, through `db`'s engine, on first use.
- `serials`: UAS ID rules; `keys`: public-key parsing; `remoteid`: the ASTM F3411 codec and
  capture reader; `errors`: bad input (exit 2) and database faults (exit 3).
"""

__all__ = ["db", "dbapi", "errors", "keys", "models", "remoteid", "serials", "store", "urls"]
