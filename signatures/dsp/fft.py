"""The one place that picks the FFT backend for radar processing.

Measured on a 2-core machine (numpy 2.4.6, scipy 1.17.1; docs/features.md
"FFT backend"): importing `scipy.fft` costs 0.19-0.38 s, a third to half of the
CLI's 0.6 s cold-start budget, while a warm `numpy.fft` transform of a 600x80
cube takes 0.17-0.25 ms against scipy's 0.15 ms. numpy's apparent slowness on
complex64 (1.0 ms) is not the transform: it is the kernel zero-filling fresh
pages for every large temporary (glibc returns >128 KiB blocks to the OS). So
the default backend is numpy, transforming in complex128 into per-thread
workspaces that are reused between calls, and handing back complex64. Set
`AUTHN_FFT=scipy` (`core.settings`, read at each call) in long batch jobs where scipy is
imported anyway: it is ~2x faster on the 8192x64 `wide` cube. A caller that knows its
workload picks per call (`fft(..., backend=...)`): a batch (`signatures.features.extract_many`)
runs scipy's single-precision transforms whatever the process default, since a batch job does
not care about the import.
"""

from __future__ import annotations

import threading

import numpy as np

from core.settings import current
from signatures.errors import SignaturesError

__all__ = ["BACKENDS", "SCIPY_WORKERS", "backend", "fft", "resolve", "rfft"]

BACKENDS = ("numpy", "scipy")
#: Threads per scipy transform. One: on a 2-core machine two threads are no faster on the
#: 8192x64 `wide` cube (0.61 against 0.58 ms, measured) and slower on the small transforms of one
#: check (the gate's 8192x5 Doppler FFT 0.17 against 0.10 ms), and a fleet runs one process per core.
#: Values do not depend on it (the threads split the rows, not a transform).
SCIPY_WORKERS = 1
_local = threading.local()


def backend() -> str:
    """The process default: 'numpy' (no import cost) or 'scipy' (faster on big cubes, 0.2-0.4 s
    import), from `AUTHN_FFT`."""
    return current().fft


def resolve(backend: str | None) -> str:
    """`backend`, or the process default for None; an unknown name raises `SignaturesError`."""
    if backend is None:
        return current().fft
    if backend not in BACKENDS:
        raise SignaturesError(f"unknown FFT backend {backend!r} (known: {', '.join(BACKENDS)})")
    return backend


def _workspace(key: str, shape: tuple[int, ...]) -> np.ndarray:
    """A complex128 scratch array reused across calls (no page faults on warm calls)."""
    spaces = getattr(_local, "spaces", None)
    if spaces is None:
        spaces = _local.spaces = {}
    buf = spaces.get(key)
    if buf is None or buf.shape != shape:
        buf = spaces[key] = np.empty(shape, dtype=np.complex128)
    return buf


def fft(x: np.ndarray, axis: int = -1, window: np.ndarray | None = None,
        inverse: bool = False, backend: str | None = None) -> np.ndarray:
    """(I)FFT of complex `x` along `axis`, optionally windowed first; complex64 result
    (complex128 for complex128 input: the float64 reference pipeline).

    `window` broadcasts against `x` (e.g. shape (n,) for the last axis or (n, 1)
    for axis 0). The result is a new array; the workspaces never escape. `backend`:
    'numpy' or 'scipy' for this call (None: the process default, `backend()`).
    """
    if resolve(backend) == "scipy":
        import scipy.fft as sfft

        out = np.complex128 if np.asarray(x).dtype == np.complex128 else np.complex64
        data = np.asarray(x, dtype=out)
        if window is not None:
            data = data * window.astype(data.real.dtype, copy=False)
        f = sfft.ifft if inverse else sfft.fft
        return f(data, axis=axis, workers=SCIPY_WORKERS).astype(out, copy=False)
    src = _workspace("in", x.shape)
    if window is None:
        src[...] = x
    else:
        np.multiply(x, window, out=src)
    dst = _workspace("out", x.shape)
    (np.fft.ifft if inverse else np.fft.fft)(src, axis=axis, out=dst)
    return dst.astype(np.complex128 if x.dtype == np.complex128 else np.complex64)


def rfft(x: np.ndarray, axis: int = -1, backend: str | None = None) -> np.ndarray:
    """Real FFT of float `x` along `axis`: numpy's (float64 arithmetic, complex128 result) or
    scipy's (the input's precision: complex64 for float32)."""
    if resolve(backend) == "scipy":
        import scipy.fft as sfft

        return sfft.rfft(x, axis=axis, workers=SCIPY_WORKERS)
    return np.fft.rfft(x, axis=axis)
