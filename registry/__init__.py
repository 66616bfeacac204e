"""Declared identities: what the registry holds and how it is read and written.

- `models`: the SQLAlchemy 2 schema of every table (registry and audit); Alembic
  (`registry/migrations/`) creates it. `db`: engines, sessions, migration on first use.
  `store`: registry queries and changes, import/export. `dbapi`: the per-check read path on
  the database driver itself (no SQLAlchemy import). `urls`: which database.
- `serials`: UAS ID rules; `keys`: public-key parsing; `remoteid`: the ASTM F3411 codec and
  capture reader; `errors`: bad input (exit 2) and database faults (exit 3).
"""

__all__ = ["db", "dbapi", "errors", "keys", "models", "remoteid", "serials", "store", "urls"]
