"""The product's errors and their exit codes, in one place.

0 accept, 1 reject, 2 bad input (the caller's fault), 3 system error (database, locks,
models, policy engine, log key). Each package keeps its own root error so that the radar
and registry layers do not import the decision layer; this module maps them all.
"""

from __future__ import annotations

EXIT_ACCEPT, EXIT_REJECT, EXIT_BAD_INPUT, EXIT_SYSTEM = 0, 1, 2, 3


class AuthnError(ValueError):
    """Bad input to the decision layer: a one-line message, no traceback (exit code 2)."""


class SystemFault(RuntimeError):
    """Something we depend on failed (database, policy engine, models, keys): exit code 3."""


class Interrupted(SystemFault):
    """SIGINT or SIGTERM arrived: the command stops with exit code 3 (what it printed is audited)."""


def bad_input_types() -> tuple[type[BaseException], ...]:
    """Every package's root error for bad input: reported in one line with exit code 2."""
    from registry.errors import RegistryError
    from signatures.errors import SignaturesError

    return (SignaturesError, RegistryError, AuthnError)


def system_fault_types() -> tuple[type[BaseException], ...]:
    """Every package's root error for system faults: reported in one line with exit code 3."""
    from registry.errors import DatabaseFault

    return (DatabaseFault, SystemFault)


def exit_code_for(exc: BaseException) -> int:
    """2 for bad input, 3 for everything else (an unexpected exception is a system error)."""
    return EXIT_BAD_INPUT if isinstance(exc, bad_input_types()) else EXIT_SYSTEM


def one_line(exc: BaseException) -> str:
    """An exception as one line for stderr and the audit log (never a traceback)."""
    text = " ".join(str(exc).split())
    return text or type(exc).__name__
