"""SIGINT/SIGTERM handling for the CLI: a stop is an `Interrupted` error (one line; exit 130 for
SIGINT, 143 for SIGTERM), never click's "Aborted!" with exit 1, which would read as a reject."""

from __future__ import annotations

import os
import signal
import sys
import threading
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
    Only the main thread can install handlers; elsewhere this does nothing.

    A handler runs between two bytecodes of the main thread, and that may be inside a finaliser
    (a weakref callback, a `__del__`), where Python prints the raised stop and drops it: the
    command would run on. While the block runs, such a dropped stop is sent again
    (`_DroppedStops`), so it is raised where it can end the command."""
    previous = {}
    for sig in STOP_SIGNALS:
        try:
            previous[sig] = signal.signal(sig, handler)
        except ValueError:  # not the main thread
            break
    hook, dropped = sys.unraisablehook, _DroppedStops()
    if previous:
        sys.unraisablehook = dropped.hook(hook)
    try:
        yield
        dropped.raise_any()  # the block ended before the stop came again
    finally:
        sys.unraisablehook = hook
        dropped.cancel()
        for sig, old in previous.items():
            signal.signal(sig, old)


class _DroppedStops:
    """Stops that Python dropped in a finaliser, each sent to this process again from a thread
    (the handler then runs once the finaliser has returned)."""

    def __init__(self) -> None:
        self.signals: list[int] = []
        self.timers: list[threading.Timer] = []

    def hook(self, other: Callable[[sys.UnraisableHookArgs], object]
             ) -> Callable[[sys.UnraisableHookArgs], object]:
        """An unraisable hook: a dropped `Interrupted` is not printed but sent again; any other
        unraisable exception goes to `other`."""
        def redeliver(unraisable: sys.UnraisableHookArgs) -> object:
            exc = unraisable.exc_value
            if not isinstance(exc, Interrupted):
                return other(unraisable)
            self.signals.append(exc.signum)
            timer = threading.Timer(0.01, os.kill, (os.getpid(), exc.signum))
            self.timers.append(timer)
            timer.start()
            return None

        return redeliver

    def raise_any(self) -> None:
        """Raise the first dropped stop, if any."""
        if self.signals:
            self.cancel()
            raise interrupted(self.signals[0])

    def cancel(self) -> None:
        for timer in self.timers:
            timer.cancel()
