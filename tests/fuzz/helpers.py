"""Shared by the fuzz tests: a SIGALRM deadline (a hang fails the test instead of blocking
CI) and the reader's contract for one file."""

from __future__ import annotations

import signal
import threading
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

CASE_SECONDS = 5.0


class Hang(BaseException):
    """Raised by `deadline`. A BaseException on purpose: the reader converts OSError
    (TimeoutError included) into RecordingError, which would hide the hang."""


@contextmanager
def deadline(seconds: float = CASE_SECONDS) -> Iterator[None]:
    """Raise Hang in the main thread after `seconds` (POSIX; a no-op elsewhere).

    Interrupts Python code and blocking system calls (open() of a FIFO); a C loop
    that retries on EINTR would still hang, so the FIFO tests also run in a subprocess.
    """
    usable = hasattr(signal, "setitimer") and threading.current_thread() is threading.main_thread()
    if not usable:
        yield
        return

    def fire(signum, frame):
        raise Hang(f"still running after {seconds} s")

    old = signal.signal(signal.SIGALRM, fire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


def read_outcome(path: Path) -> tuple[str, str]:
    """("valid", "") or ("bad", message) for a file; any other exception propagates."""
    from signatures.errors import RecordingError
    from signatures.recording import Recording, read_recording

    try:
        rec = read_recording(path)
    except RecordingError as exc:
        return "bad", str(exc)
    assert isinstance(rec, Recording)
    return "valid", ""


def check_recording(rec) -> None:
    """What a returned Recording guarantees (the pipeline relies on it)."""
    import numpy as np

    assert rec.iq.ndim == 2 and rec.iq.size > 0
    assert rec.iq.dtype in (np.dtype(np.complex64), np.dtype(np.complex128))  # native byte order
    assert np.isfinite(rec.iq).all()
    rec.mid_time  # no OverflowError
    if rec.remote_id is not None:
        assert rec.remote_id.dtype == np.uint8 and rec.remote_id.shape[1:] == (25,)
    if rec.remote_id_time_s is not None:
        assert rec.remote_id_time_s.dtype == np.float64 and rec.remote_id_time_s.dtype.isnative


def is_one_line(text: str) -> bool:
    return bool(text.strip()) and "\n" not in text.strip() and "\r" not in text

