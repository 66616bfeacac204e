"""How an `authn` process runs: settings that belong to the application, not to the library.

`signatures` and the other packages leave process-wide state alone; the console entry point
(`authn.__main__`) applies `tune()` once, before the command line is imported, and `authn serve --workers`
applies it in each spawned worker (`authn.service.workers`). Scripts that time the CLI's work
(benchmarks/batch_stages.py) apply it too, so they time what a user's `authn` process does.
"""

from __future__ import annotations

import ctypes
import gc
import sys

__all__ = ["GC_THRESHOLD0", "MMAP_THRESHOLD_BYTES", "TRIM_THRESHOLD_BYTES", "exit_quickly", "hold_freed_memory",
           "tune"]

#: The first-generation GC threshold (CPython's default: 700). Importing what a check needs
#: allocates ~80 000 container objects, none of them garbage: at 700 that ran ~40 ms of
#: collections (a tenth of a cold check) that freed nothing. Long jobs (batches, `serve`) still
#: collect, every 100 000 net allocations.
GC_THRESHOLD0 = 100_000

#: glibc serves blocks under this from its heap rather than from fresh mappings. A batch's
#: working arrays (0.1-32 MB each, freed and made again for every block of rows) otherwise come
#: from fresh mappings, whose every page is faulted in and zeroed on first touch: 13 000 faults
#: per `paper` batch of 256 returns, ~9 % of its time (docs/benchmarks.md, "Batch mode").
#: Larger arrays still map and unmap (the cube stage keeps its own workspaces).
MMAP_THRESHOLD_BYTES = 32 * 2**20
#: ... and gives its free top back to the system beyond this, not beyond glibc's 128 KiB: a
#: process keeps up to this much freed memory for its next batch.
TRIM_THRESHOLD_BYTES = 128 * 2**20

_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3  # malloc.h


def hold_freed_memory() -> bool:
    """Set glibc's mmap and trim thresholds (`MMAP_THRESHOLD_BYTES`, `TRIM_THRESHOLD_BYTES`);
    False where the C library is not glibc (nothing changes). Process-wide and lasting: glibc
    stops adapting its thresholds once they are set."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(None)  # the process's own symbols: its C library's among them
    except OSError:
        return False
    if not (hasattr(libc, "gnu_get_libc_version") and hasattr(libc, "mallopt")):  # musl's mallopt does nothing
        return False
    mallopt = libc.mallopt
    mallopt.argtypes, mallopt.restype = [ctypes.c_int, ctypes.c_int], ctypes.c_int
    return bool(mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES)) and bool(
        mallopt(_M_TRIM_THRESHOLD, TRIM_THRESHOLD_BYTES))


def exit_quickly() -> None:
    """Before the interpreter exits: move every object out of the collector's reach (`gc.freeze`).
    Finalisation still runs (modules torn down, files and connections closed, atexit handlers),
    but its full collection no longer walks the ~100 000 objects a check leaves, none of them
    garbage that matters to a process about to end: 70-95 ms of a cold `authn check FILE --json`
    (2 cores). Everything the command printed was committed before it was printed."""
    gc.freeze()


def tune() -> None:
    """The `authn` process's settings: the GC threshold and glibc's memory thresholds."""
    gc.set_threshold(GC_THRESHOLD0, *gc.get_threshold()[1:])
    hold_freed_memory()
