"""The two-pass histogram percentiles of the per-pair summary equal numpy's ('linear')."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from clothtool.analysis.output.percentiles import percentiles

QS = np.array([0.0, 5.0, 50.0, 95.0, 100.0])


@settings(max_examples=300, deadline=None)
@given(arrays(np.float64, st.integers(1, 300),
              elements=st.floats(-1e6, 1e6, allow_nan=False, allow_subnormal=False)))
def test_equals_numpy_on_random_arrays(values):
    np.testing.assert_allclose(percentiles(values, QS), np.percentile(values, QS),
                               rtol=1e-12, atol=1e-12 * np.abs(values).max())


@settings(max_examples=100, deadline=None)
@given(st.integers(1, 5000), st.integers(1, 4), st.integers(0, 2**32 - 1))
def test_many_ties_and_float32(n, distinct, seed):
    """Few distinct values (most of a bin identical), float32 input as in /face/stretch."""
    rng = np.random.default_rng(seed)
    values = rng.choice(rng.random(distinct) + 0.5, n).astype(np.float32)
    np.testing.assert_allclose(percentiles(values, QS), np.percentile(values, QS), rtol=1e-7)


def test_edge_cases():
    assert np.isnan(percentiles(np.zeros(0), QS)).all()
    np.testing.assert_array_equal(percentiles(np.full(7, 2.5), QS), 2.5)
    np.testing.assert_allclose(percentiles(np.array([3.0, 1.0]), QS), [1.0, 1.1, 2.0, 2.9, 3.0])
    # a range so small that BINS / (max − min) overflows: the sorting fallback
    tiny = np.array([0.0, 2.2250738585072014e-308, 0.0, 5e-324, 0.0])
    np.testing.assert_array_equal(percentiles(tiny, QS), np.percentile(tiny, QS))
    # a wide spread with a cluster: the wanted ranks fall inside one crowded bin
    values = np.concatenate([np.linspace(0, 1e6, 50), 1.0 + 1e-9 * np.arange(10000)])
    np.testing.assert_allclose(percentiles(values, QS), np.percentile(values, QS), rtol=1e-12)
