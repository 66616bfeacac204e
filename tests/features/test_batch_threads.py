"""`signatures.dsp.threads.one_blas_thread`: one BLAS thread inside, the same products to float32
rounding, the original limits back after (nested and overlapping blocks included);
`blas_on_one_thread` says so, and on one thread the batch path's stacked sub-chirp products are
the single path's to within `ULPS` float32 ulps of the row's largest bin.

A product's bits may change with the thread count and with the height of the stacked product
(BLAS kernels split and order their sums by both), so no comparison across them is bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from signatures.dsp import extraction as bf
from signatures.dsp import flash_series as est
from signatures.dsp import threads
from signatures.dsp.cube_scale import SAFE_EXPONENT

#: float32 ulps (of a row's largest magnitude) a product may move by between thread counts or
#: stack heights: a 48-term complex sum accumulated in another order
ULPS = 16
EPS32 = float(np.finfo(np.float32).eps)


def _blas_threads() -> list[int]:
    controller = threads._get_controller()
    if controller is None:
        pytest.skip("threadpoolctl cannot see a BLAS library here")
    return [lib.num_threads for lib in controller.select(user_api="blas").lib_controllers]


def test_one_thread_inside_and_the_limits_restored():
    before = _blas_threads()
    assert not threads.blas_on_one_thread()
    with threads.one_blas_thread():
        assert all(n == 1 for n in _blas_threads()) and threads.blas_on_one_thread()
        with threads.one_blas_thread():  # nested: still one, and the outer block keeps it
            assert all(n == 1 for n in _blas_threads())
        assert all(n == 1 for n in _blas_threads()) and threads.blas_on_one_thread()
    assert _blas_threads() == before
    assert not threads.blas_on_one_thread()


def test_same_products_on_one_thread():
    rng = np.random.default_rng(0)
    a, b = rng.standard_normal((256, 29)), rng.standard_normal((29, 8000))
    ref = a @ b
    with threads.one_blas_thread():
        one = a @ b
    assert np.abs(one - ref).max() <= 64 * np.finfo(np.float64).eps * np.abs(ref).max()


def test_stacked_subchirp_bins_are_the_row_by_row_products_to_float32_rounding():
    """On one BLAS thread the batch path stacks rows that share a peak bin and a scale into one
    product; each row's bins are those of its own `flash_series.subchirp_bins` call (what the
    batch path makes row by row, and the single path makes) to within ULPS of the row's largest
    bin. Rows of 37 chirps: products whose height is not the single path's block of 64; one row
    beyond the safe exponent."""
    _blas_threads()
    rng = np.random.default_rng(3)
    n_rows, n_chirps, n_samples, window = 23, 37, 80, 48
    iq = (rng.standard_normal((n_rows, n_chirps, n_samples))
          + 1j * rng.standard_normal((n_rows, n_chirps, n_samples))).astype(np.complex64)
    iq *= np.ldexp(1.0, rng.choice([-3, 0, 5, 30], n_rows)).astype(np.float32)[:, None, None]
    log2_scale = bf.prepared(iq, list(range(n_rows)))[2]
    peak = rng.choice([2, 17, 40], n_rows)
    args = (iq, np.arange(n_rows), peak, log2_scale, list(range(n_rows)), window)
    assert not threads.blas_on_one_thread()
    row_by_row = bf._subchirp_bins(*args)
    with threads.one_blas_thread():
        assert threads.blas_on_one_thread()
        stacked = bf._subchirp_bins(*args)
        for b in range(n_rows):
            tol = ULPS * EPS32 * np.abs(row_by_row[b]).max()
            assert np.abs(stacked[b] - row_by_row[b]).max() <= tol, b
            if abs(log2_scale[b]) <= SAFE_EXPONENT:
                want = est.subchirp_bins(iq[b], int(peak[b]), window, 2.0 ** -int(log2_scale[b]))
                assert np.abs(stacked[b] - want).max() <= tol, b
