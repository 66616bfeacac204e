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
    _ = rec.mid_time  # a property: computing it raises no OverflowError
    if rec.remote_id is not None:
        assert rec.remote_id.dtype == np.uint8 and rec.remote_id.shape[1:] == (25,)
    if rec.remote_id_time_s is not None:
        assert rec.remote_id_time_s.dtype == np.float64 and rec.remote_id_time_s.dtype.isnative


def is_one_line(text: str) -> bool:
    return bool(text.strip()) and "\n" not in text.strip() and "\r" not in text



def read_in_child(path: Path, seconds: float = CASE_SECONDS) -> tuple[str, str]:
    """`read_outcome` (plus `check_recording`) in a forked child, killed after `seconds`.

    SIGALRM cannot stop a loop inside the HDF5 C library (one such loop, on a corrupt
    global heap, was found by the property test); a child process can be killed.
    Returns ("valid", ""), ("bad", message), ("hang", "") or ("crash", description).
    Falls back to in-process reading where fork is unavailable.
    """
    import json
    import os
    import select
    import traceback

    if not hasattr(os, "fork"):
        with deadline(seconds):
            return read_outcome(path)
    rfd, wfd = os.pipe()
    pid = os.fork()
    if pid == 0:  # child: never return into pytest
        code = 0
        try:
            os.close(rfd)
            try:
                got, msg = read_outcome(path)
                if got == "valid":
                    from signatures.recording import read_recording

                    check_recording(read_recording(path))
            except BaseException as exc:  # noqa: BLE001
                got, msg = "crash", "".join(traceback.format_exception_only(type(exc), exc)).strip()
            os.write(wfd, json.dumps([got, msg]).encode())
        except BaseException:  # noqa: BLE001
            code = 1
        finally:
            os._exit(code)
    os.close(wfd)
    try:
        ready, _, _ = select.select([rfd], [], [], seconds)
        if not ready:
            os.kill(pid, signal.SIGKILL)
            return "hang", ""
        chunks = []
        while True:
            block = os.read(rfd, 65536)
            if not block:
                break
            chunks.append(block)
        data = b"".join(chunks)
        return tuple(json.loads(data)) if data else ("crash", "child died without a result")
    finally:
        os.close(rfd)
        os.waitpid(pid, 0)
