"""Database URLs: `--db`, then $AUTHN_DATABASE_URL, then a SQLite file in the user data dir.

Kept free of SQLAlchemy so that the per-check path can resolve a URL cheaply.

Two rules keep a typo from silently becoming an empty registry (every check `unregistered`):

* only `sqlite` and `postgresql` URLs are accepted (`check_backend`), by name;
* a SQLite file is created only in a directory that exists (`prepare_sqlite`). The default
  database's directory (the user data dir) is made on first use, as is the directory of a
  database created on purpose (`authn db upgrade --create`); any other missing directory
  is bad input, never `mkdir -p`. A new file is announced through `created_notice` (the
  CLI prints one line on stderr).
"""

from __future__ import annotations

import re
from collections.abc import Callable
from pathlib import Path

#: The database backends we ship drivers for and test (`+driver` suffixes allowed).
SUPPORTED_BACKENDS = ("sqlite", "postgresql")
#: Called with the URL of each SQLite database file this process creates; None: silent.
#: The CLI sets it to print `authn: created new database URL (empty registry)` on stderr.
created_notice: Callable[[str], None] | None = None


def default_url() -> str:
    """SQLite file `registry.sqlite3` in the platform's user data directory."""
    from platformdirs import user_data_dir

    return f"sqlite:///{Path(user_data_dir('authn')) / 'registry.sqlite3'}"


def resolve_url(url: str | None = None) -> str:
    """Explicit URL, else $AUTHN_DATABASE_URL, else the default SQLite file.

    Bare `postgresql://` URLs get the psycopg (3) driver, the one we ship.
    """
    from core.settings import current

    url = url or current().database_url or default_url()
    for prefix in ("postgresql://", "postgres://"):
        if url.startswith(prefix):
            return "postgresql+psycopg://" + url[len(prefix):]
    return url


def check_backend(url: str) -> str:
    """The backend of a resolved URL, 'sqlite' or 'postgresql'; anything else (a typo, a
    path without a scheme, another database) is bad input naming the supported ones."""
    from registry.errors import RegistryError

    scheme = url.split("://", 1)[0] if "://" in url else ""
    backend = scheme.split("+", 1)[0].lower()
    if backend not in SUPPORTED_BACKENDS:
        shown = re.sub(r"(://[^/:@]*:)[^/@]*@", r"\1***@", url)  # never echo a password
        what = f"{shown!r}: scheme {scheme!r} is not supported" if scheme else f"{shown!r} is not a URL"
        raise RegistryError(f"--db {what}; use sqlite:///PATH or postgresql://USER@HOST/DB "
                            f"(supported: {', '.join(SUPPORTED_BACKENDS)})")
    return backend


def sqlite_file(url: str) -> Path | None:
    """The file of a resolved SQLite URL (`~` expanded); None for an in-memory one or not SQLite."""
    if not url.lower().startswith("sqlite"):
        return None
    rest = url.split(":///", 1)[1] if ":///" in url else ""
    rest = rest.split("?", 1)[0]
    if rest in ("", ":memory:") or rest.startswith("file::memory:"):
        return None
    return Path(rest).expanduser()


def prepare_sqlite(url: str, *, create: bool = False) -> bool:
    """Before a SQLite URL is opened: True when its file does not exist yet (the open will
    create it: call `announce_created` once that worked). A missing directory is made only for
    the default database or when `create` (`authn db upgrade --create`); otherwise it is bad
    input. A path whose directory is a file is left to the open, which fails (exit 3)."""
    from registry.errors import DatabaseFault, RegistryError

    path = sqlite_file(url)
    if path is None or path.exists():
        return False
    parent = path.parent
    if not parent.exists():
        if not (create or url == default_url()):
            raise RegistryError(f"--db: directory {parent} does not exist; create the database on purpose "
                                "with `authn db upgrade --create`")
        try:
            parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise DatabaseFault(f"cannot create the database directory {parent}: {exc.strerror}") from None
    return True


def announce_created(url: str) -> None:
    """Tell `created_notice` (if any) that this process created the SQLite database `url`."""
    if created_notice is not None:
        created_notice(url)
