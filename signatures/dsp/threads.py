"""One BLAS thread for batches of returns.

A batch job runs one process per core (one thread per scipy transform), but OpenBLAS starts a
thread per core for every matrix product big enough (the kNN distances of a batch, the flash
estimators' stacked products). On a machine whose other core is busy those threads wait for
each other: measured on the shared 2-core machine, the `paper` batch of 256 (features +
classifier) took 0.97 ms per return with the default BLAS threads and 0.72 ms with one. The
number of threads can also change a product's last bits (a complex (128-256 x 80) by (80 x 9)
product differs between one and two threads, OpenBLAS 0.3.31), so a return's features would
depend on its batch: products are kept too small to be split (`flash_series.SUBCHIRP_BLOCK`).

On one thread a product's rows do not depend on how many rows it has (OpenBLAS 0.3.31, complex64,
measured), so inside the block (`blas_on_one_thread()`) a batch may stack many rows into one
product: the sub-chirp bins of a `paper` batch cost about a third less that way. That holds for
that build, not for every BLAS: elsewhere a stacked row may differ in its last bits, so the tests
compare stacked and row-by-row products to float32 rounding, not bit for bit.

`one_blas_thread()` limits the loaded BLAS libraries to one thread for a block of code
(threadpoolctl, a scikit-learn dependency; nothing happens without it). Its controller is made
on first use (~15 ms, once per process), after numpy's BLAS is loaded.
"""

from __future__ import annotations

import contextlib
import threading

__all__ = ["blas_on_one_thread", "one_blas_thread"]

_lock = threading.Lock()
_controller = None
_tried = False
_active = 0  # blocks inside `one_blas_thread`
_limiter = None


def _get_controller():
    global _controller, _tried
    if not _tried:
        with _lock:
            if not _tried:
                try:
                    from threadpoolctl import ThreadpoolController

                    controller = ThreadpoolController()
                    _controller = controller if controller.select(user_api="blas").lib_controllers else None
                except Exception:  # noqa: BLE001 - no threadpoolctl, or a library it cannot inspect: leave BLAS alone
                    _controller = None
                _tried = True
    return _controller


@contextlib.contextmanager
def one_blas_thread():
    """The loaded BLAS libraries use one thread inside this block (a no-op without
    threadpoolctl). The limit is process-wide: overlapping blocks of several threads share it,
    set by the first to enter and lifted when the last leaves."""
    global _active, _limiter
    controller = _get_controller()
    if controller is None:
        yield
        return
    with _lock:
        if _active == 0:
            _limiter = controller.limit(limits=1, user_api="blas")
        _active += 1
    try:
        yield
    finally:
        with _lock:
            _active -= 1
            if _active == 0 and _limiter is not None:
                _limiter.restore_original_limits()
                _limiter = None


def blas_on_one_thread() -> bool:
    """Whether BLAS is held to one thread now: inside `one_blas_thread` with a BLAS it controls."""
    return _active > 0 and _limiter is not None
