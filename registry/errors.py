"""Errors of the registry layer: the caller's fault (exit code 2) or the database's (exit code 3)."""

from core.errors import BadInput, SystemFault

__all__ = ["RegistryError", "DatabaseFault"]


class RegistryError(BadInput):
    """Bad input to the registry or the Remote ID codec: a one-line message."""


class DatabaseFault(SystemFault):
    """The database cannot serve us (unopenable, read-only, locked, lost): a system error, not bad input."""
