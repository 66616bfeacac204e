"""`flash_series.window_sums`, the flash series' moving sums: exact windows, clipped ends, and
rounding that follows a window's own samples rather than the dwell's history."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from signatures.dsp.flash_series import window_sums


def _direct(z: np.ndarray, half: int) -> np.ndarray:
    n = z.shape[0]
    return np.array([z[max(t - half, 0):min(t + half + 1, n)].sum(axis=0) for t in range(n)])


@settings(max_examples=150, deadline=None)
@given(n=st.integers(1, 300), half=st.integers(0, 40), cols=st.integers(1, 4), rows=st.integers(1, 3),
       log_scale=st.floats(-30, 30), seed=st.integers(0, 2**32 - 1))
def test_sums_of_clipped_centred_windows(n, half, cols, rows, log_scale, seed) -> None:
    rng = np.random.default_rng(seed)
    z = ((rng.standard_normal((rows, n, cols)) + 1j * rng.standard_normal((rows, n, cols)))
         * np.exp(log_scale)).astype(np.complex64)
    got = window_sums(z, half, axis=1)
    assert got.shape == z.shape and got.dtype == z.dtype
    want = np.stack([_direct(r.astype(np.complex128), half) for r in z])
    magnitude = np.stack([_direct(np.abs(r).astype(np.float64), half) for r in z])
    # float32 rounding of a sum of at most 2 half + 1 terms, on the window's own magnitudes
    bound = (np.log2(2 * half + 1) + 2) * 2 * np.finfo(np.float32).eps * magnitude
    assert np.all(np.abs(got - want) <= bound + np.finfo(np.float32).tiny)
    # the batch axis changes nothing: a row alone is the same floats
    np.testing.assert_array_equal(window_sums(z[0], half, axis=0), got[0])


def test_strong_early_samples_leave_later_windows_exact() -> None:
    """Clutter 100 dB over the rest in the first half of a dwell: a running-sum difference in
    float32 carries ~1e-7 of the 1e5-amplitude total into every later window (about 0.1, against
    windows of ~1); these sums stay at float32 rounding of their own samples."""
    rng = np.random.default_rng(3)
    n, half = 600, 4
    z = (rng.standard_normal((n, 3)) + 1j * rng.standard_normal((n, 3))).astype(np.complex64)
    z[:300] *= np.float32(1e5)
    got = window_sums(z, half)[320:]
    want = _direct(z.astype(np.complex128), half)[320:]
    assert np.max(np.abs(got - want) / np.abs(want)) < 1e-5
    c = np.concatenate([np.zeros((1, 3), np.complex64), np.cumsum(z, axis=0)])
    running = (c[2 * half + 1:] - c[:-2 * half - 1])[320 - half:]
    assert np.max(np.abs(running - want[:len(running)])) > 1e-2  # what the old form lost
