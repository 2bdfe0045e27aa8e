"""``driftlog._blas.dot``: np.dot's own sum, bit for bit, without waking the BLAS's threads."""

import numpy as np
import pytest

from driftlog import _blas


@pytest.mark.parametrize("n", [7, 10_000, 10_001, 46_691, 100_003])
def test_dot_is_np_dot_bit_for_bit(n):
    rng = np.random.default_rng(n + 1)
    for scale in (1.0, 1e-3, 1e6):
        a = rng.standard_normal(n) * scale
        b = np.abs(rng.standard_normal(n)) * rng.integers(0, 2, n)  # depths with dry faces
        assert _blas.dot(a, b) == float(np.dot(a, b))
        assert _blas.dot(b, a) == float(np.dot(b, a))


def test_split_parts_cover_the_vector_once():
    # the parts of a k-way split, each summed alone and added in order: with integers (exact
    # sums) the result is the plain sum for any thread count, so no entry is left out or doubled
    blas = _blas._blas()
    if blas is None:
        pytest.skip("numpy's BLAS is not OpenBLAS: dot is np.dot")
    ctl, _ = blas
    a = np.arange(46_691, dtype=float)
    b = np.ones_like(a)
    for threads in (1, 2, 3, 8):
        assert _blas._split_dot(ctl, a, b, threads) == a.sum()
