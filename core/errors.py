"""The product's errors and their exit codes, in one place.

0 accept, 1 reject, 2 bad input (the caller's fault), 3 system error (database, locks, models,
policy engine, log key), 4 inconclusive (the evidence decided neither way: not an accept).
Every error the product raises on purpose derives from `AuthnException` and carries its exit
code; the CLI maps exceptions to exit codes only through `exit_code_for`. This module imports
nothing but the leaf `core.textsafe`, so the radar (`signatures`) and registry layers derive
their own roots from it without importing the decision layer. The one line an error becomes has
its control characters escaped (`core.textsafe.printable`): a serial or file name with an ESC
in it never reaches the terminal raw. Rejections are not errors: they are decisions, with the
policy ids as reasons.
"""

from __future__ import annotations

from core.textsafe import printable

__all__ = ["EXIT_ACCEPT", "EXIT_REJECT", "EXIT_BAD_INPUT", "EXIT_SYSTEM", "EXIT_INCONCLUSIVE", "AuthnException",
           "BadInput",
           "SystemFault", "Interrupted", "AuthnError", "OverLimit", "describe", "exit_code_for", "one_line"]

EXIT_ACCEPT, EXIT_REJECT, EXIT_BAD_INPUT, EXIT_SYSTEM, EXIT_INCONCLUSIVE = 0, 1, 2, 3, 4
#: Many results' one exit code is the worst: system error, bad input, reject, inconclusive, accept.
_SEVERITY = (EXIT_ACCEPT, EXIT_INCONCLUSIVE, EXIT_REJECT, EXIT_BAD_INPUT, EXIT_SYSTEM)


def exit_code_of(decision: str) -> int:
    """A decision's exit code: 0 accept, 4 inconclusive, 1 reject (and anything else)."""
    return {"accept": EXIT_ACCEPT, "inconclusive": EXIT_INCONCLUSIVE}.get(decision, EXIT_REJECT)


def worst(codes: "list[int]") -> int:
    """The exit code of many results (`_SEVERITY`); 0 for none."""
    return max(codes, key=lambda c: _SEVERITY.index(c) if c in _SEVERITY else len(_SEVERITY), default=EXIT_ACCEPT)


class AuthnException(Exception):
    """Root of every error the product reports: one line on stderr, never a traceback."""

    exit_code = EXIT_SYSTEM


class BadInput(AuthnException, ValueError):
    """The caller's fault: a file, message, option, policy or record that is not valid (exit 2)."""

    exit_code = EXIT_BAD_INPUT


class SystemFault(AuthnException, RuntimeError):
    """Something we depend on failed (database, policy engine, models, keys): exit code 3."""

    exit_code = EXIT_SYSTEM


class Interrupted(BaseException):
    """SIGINT or SIGTERM arrived: the command stops (what it printed is audited) with the shell's
    code for that signal, 128 + its number: 130 for SIGINT, 143 for SIGTERM. A BaseException, as
    KeyboardInterrupt is: the handlers that turn one file's failure into that file's error (and
    go on with the batch) catch Exception, and must not swallow a stop."""

    def __init__(self, message: str, signum: int) -> None:
        super().__init__(message)
        self.signum = signum
        self.exit_code = 128 + signum


class AuthnError(BadInput):
    """Bad input to the decision layer (options, claims, checkpoints, policies)."""


class OverLimit(AuthnError):
    """Input that would fan out into more decisions than a configured cap allows (a capture
    naming more drones than the limit): bad input (exit 2), the service's 413."""


def exit_code_for(exc: BaseException) -> int:
    """The exit code of an exception: its own for ours (a stop's: 130 or 143), 3 for anything
    unexpected."""
    return exc.exit_code if isinstance(exc, (AuthnException, Interrupted)) else EXIT_SYSTEM


def one_line(exc: BaseException) -> str:
    """An exception as one line for stderr and the audit log (never a traceback); control and
    bidi characters from untrusted input escaped as `\\x1b` / `\\u202e`."""
    text = printable(" ".join(str(exc).split()))
    return text or type(exc).__name__


#: optional dependencies (pyproject extras) by top-level module: a check needs none of them
OPTIONAL_EXTRAS = {"sklearn": "train", "onnx": "train", "matplotlib": "plot",
                   "torch": "cnn", "dask": "cluster", "distributed": "cluster", "locust": "dev"}


def describe(exc: BaseException) -> str:
    """An exception as the one line the CLI prints after "error: " and the audit keeps: ours
    as their message, a missing optional dependency as the extra to install, anything else
    as "internal error: Type: message" (a driver error that SQLAlchemy wraps with the SQL
    and a link: the driver's message)."""
    if isinstance(exc, (AuthnException, Interrupted)):
        return one_line(exc)
    if isinstance(exc, ModuleNotFoundError) and (exc.name or "").split(".")[0] in OPTIONAL_EXTRAS:
        extra = OPTIONAL_EXTRAS[(exc.name or "").split(".")[0]]
        return (f"this command needs the optional '{extra}' dependencies ({exc.name} is not installed): "
                f"pip install 'uav-radar-authn[{extra}]'")
    orig = getattr(exc, "orig", None)
    if orig is not None:
        return f"internal error: database: {one_line(orig)}"
    return f"internal error: {type(exc).__name__}: {one_line(exc)}"
