"""A registry for a test: identities registered active from 2020, each (serial, model)."""

from __future__ import annotations

from datetime import datetime, timezone

VALID_FROM = datetime(2020, 1, 1, tzinfo=timezone.utc)


def register(db_url: str, *identities: tuple[str, str]) -> None:
    """Register each (serial, model) as an active identity valid from `VALID_FROM`."""
    from registry.dbapi import transaction
    from registry.store import NewIdentity, register_identity

    with transaction(db_url) as s:
        for serial, model in identities:
            register_identity(s, NewIdentity(serial=serial, model=model, operator_id="TEST", valid_from=VALID_FROM))
