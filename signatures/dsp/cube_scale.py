"""The host pass every cube stage starts with (numpy in `signatures.dsp.extraction`, torch in
`signatures.dsp.torch_cube`): input checks per row and the exact power-of-two scale.

A module of its own so that both cube stages import it and neither imports the other.
"""

from __future__ import annotations

import numpy as np

__all__ = ["SAFE_EXPONENT", "STILL_TOLERANCE", "RowError", "prepared"]

#: cubes whose peak lies within 2**+-this of 1 are scaled on the window (`signatures.dsp.extraction`)
SAFE_EXPONENT = 20
#: chirps that differ by at most this much of the cube's peak are the same chirp (64 float32 ulps):
#: a cube of one repeated chirp carries no slow-time signal, only the rounding of its transforms
STILL_TOLERANCE = 64 * float(np.finfo(np.float32).eps)


class RowError(Exception):
    """Bad input in one row: `signatures.dsp.extraction` words it for a batch or for a single return."""

    def __init__(self, row: int, message: str) -> None:
        super().__init__(message)
        self.row, self.message = row, message


def prepared(a: np.ndarray, labels: list[int]) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """`rd.prepare` of every row, but for the scale: (x complex64, scale (B, 1, 1) float64 that is
    still to apply, log2 scale, no-signal flag (`_still`)); a NaN or Inf raises naming its row.

    The exact power-of-two scale s commutes with every rounding while nothing under- or
    overflows, so for cubes within 2**+-SAFE_EXPONENT of unit scale it rides on the window,
    (x - m) * (w * s), saving a pass over the cube; other cubes are scaled here (scale 1).
    """
    if a.dtype in (np.complex64, np.float32, np.float16) or np.issubdtype(a.dtype, np.integer):
        work = np.ascontiguousarray(a, dtype=np.complex64)
    else:
        work = np.ascontiguousarray(a, dtype=np.complex128)
    flat = work.view(work.real.dtype).reshape(work.shape[0], -1)
    peak = np.maximum(flat.max(axis=1), -flat.min(axis=1)).astype(np.float64)  # NaN/Inf propagate
    bad = ~np.isfinite(peak)
    if bad.any():
        raise RowError(labels[int(np.argmax(bad))], "IQ cube holds NaN or Inf")
    zero = peak == 0.0
    exponent = np.where(zero, 0, np.frexp(np.where(zero, 1.0, peak))[1])
    scale = np.ldexp(1.0, -exponent)[:, None, None]
    zero = zero | _still(work, peak)
    if np.all(np.abs(exponent) <= SAFE_EXPONENT):
        return work.astype(np.complex64, copy=False), scale, exponent, zero
    # as rd.prepare: exact in complex64 where it can, else via complex128
    small = work.dtype == np.complex64 and bool(np.all((exponent >= -127) & (exponent <= 126)))
    x = work * scale.astype(np.float32) if small else (work.astype(np.complex128) * scale).astype(np.complex64)
    return x, np.ones_like(scale), exponent, zero


def _still(work: np.ndarray, peak: np.ndarray) -> np.ndarray:
    """Rows (B, chirps, samples) whose every chirp equals the first to within `STILL_TOLERANCE` of
    the row's peak. Such a cube (a constant one, say) has no slow-time signal: what its
    clutter-suppressed spectra hold is rounding, whose pattern depends on the memory layout of
    the batch, so its counts would too. They are treated as all-zero cubes."""
    still = np.zeros(work.shape[0], bool)
    if work.shape[1] < 2:
        return still
    tol = STILL_TOLERANCE * peak
    screen = np.abs(work[:, -1] - work[:, 0]).max(axis=1) <= tol  # the last chirp against the first
    for b in np.flatnonzero(screen & (peak > 0.0)).tolist():
        still[b] = bool(np.abs(work[b] - work[b, :1]).max() <= tol[b])
    return still
