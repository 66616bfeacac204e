"""`signatures.dsp.stats.median` equals `np.median` on finite input (it only avoids importing numpy.ma)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from signatures.dsp.stats import median


@settings(max_examples=60, deadline=None)
@given(a=arrays(np.float32, st.tuples(st.integers(1, 7), st.integers(1, 9)),
                elements=st.floats(-2.0**60, 2.0**60, width=32)),
       axis=st.sampled_from([None, 0, 1]))
def test_matches_numpy(a: np.ndarray, axis: int | None) -> None:
    np.testing.assert_allclose(median(a, axis=axis), np.median(a, axis=axis), rtol=1e-6, atol=0)


def test_empty_is_an_error() -> None:
    with pytest.raises(ValueError):
        median(np.zeros(0))


@settings(max_examples=100, deadline=None)
@given(values=st.lists(st.integers(-50, 50), min_size=1, max_size=40), q=st.floats(0, 100))
def test_quantile_and_distinct_are_numpys(values, q):
    from signatures.dsp.stats import distinct, quantile

    assert quantile(np.array(values), q) == pytest.approx(float(np.percentile(values, q)), abs=1e-9)
    assert distinct(np.array(values)) == np.unique(values).tolist()
