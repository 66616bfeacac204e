"""`signatures.threads.one_blas_thread`: one BLAS thread inside, the same products, the
original limits back after (nested and overlapping blocks included)."""

from __future__ import annotations

import numpy as np
import pytest

from signatures import threads


def _blas_threads() -> list[int]:
    controller = threads._get_controller()
    if controller is None:
        pytest.skip("threadpoolctl cannot see a BLAS library here")
    return [lib.num_threads for lib in controller.select(user_api="blas").lib_controllers]


def test_one_thread_inside_and_the_limits_restored():
    before = _blas_threads()
    with threads.one_blas_thread():
        assert all(n == 1 for n in _blas_threads())
        with threads.one_blas_thread():  # nested: still one, and the outer block keeps it
            assert all(n == 1 for n in _blas_threads())
        assert all(n == 1 for n in _blas_threads())
    assert _blas_threads() == before


def test_same_products_on_one_thread():
    rng = np.random.default_rng(0)
    a, b = rng.standard_normal((256, 29)), rng.standard_normal((29, 8000))
    ref = a @ b
    with threads.one_blas_thread():
        assert np.array_equal(a @ b, ref)
