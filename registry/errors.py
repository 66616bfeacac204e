"""Errors of the registry layer that are the caller's fault (exit code 2)."""


class RegistryError(ValueError):
    """Bad input to the registry or the Remote ID codec: a one-line message."""
