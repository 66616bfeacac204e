"""Database URLs: `--db`, then $AUTHN_DATABASE_URL, then a SQLite file in the user data dir.

Kept free of SQLAlchemy so that the per-check path can resolve a URL cheaply.
"""

from __future__ import annotations

import os
from pathlib import Path

ENV_URL = "AUTHN_DATABASE_URL"


def default_url() -> str:
    """SQLite file `registry.sqlite3` in the platform's user data directory."""
    from platformdirs import user_data_dir

    return f"sqlite:///{Path(user_data_dir('authn')) / 'registry.sqlite3'}"


def resolve_url(url: str | None = None) -> str:
    """Explicit URL, else $AUTHN_DATABASE_URL, else the default SQLite file.

    Bare `postgresql://` URLs get the psycopg (3) driver, the one we ship.
    """
    url = url or os.environ.get(ENV_URL) or default_url()
    for prefix in ("postgresql://", "postgres://"):
        if url.startswith(prefix):
            return "postgresql+psycopg://" + url[len(prefix):]
    return url
