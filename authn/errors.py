"""Errors of the decision layer that are the caller's fault (exit code 2)."""


class AuthnError(ValueError):
    """Bad input to the decision layer: a one-line message, no traceback."""
