"""Errors of the decision layer that are the caller's fault (exit code 2)."""


class AuthnError(ValueError):
    """Bad input to the decision layer: a one-line message, no traceback."""


def bad_input_types() -> tuple[type[BaseException], ...]:
    """Every package's root error: bad input, reported in one line with exit code 2."""
    from registry.errors import RegistryError
    from signatures.errors import SignaturesError

    return (SignaturesError, RegistryError, AuthnError)
