"""SIGINT/SIGTERM handling for the CLI: a stop is an `Interrupted` error (one line; exit 130 for
SIGINT, 143 for SIGTERM), never click's "Aborted!" with exit 1, which would read as a reject."""

from __future__ import annotations

import signal
from collections.abc import Callable, Iterator
from contextlib import contextmanager

from core.errors import Interrupted

__all__ = ["handled", "interrupted"]

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


def interrupted(signum: int) -> Interrupted:
    """The error a stop signal raises (its exit code: 128 + the signal's number)."""
    return Interrupted(f"interrupted by {signal.Signals(signum).name}", signum)


@contextmanager
def handled(handler: Callable[[int, object], None]) -> Iterator[None]:
    """`handler` for SIGINT and SIGTERM while the block runs, the previous handlers after it.
    Only the main thread can install handlers; elsewhere this does nothing."""
    previous = {}
    for sig in STOP_SIGNALS:
        try:
            previous[sig] = signal.signal(sig, handler)
        except ValueError:  # not the main thread
            break
    try:
        yield
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)
