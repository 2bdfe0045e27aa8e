"""The solver's volume (docs/model.md (20)): a compensated sum, the same on every machine."""

import math

import numpy as np

from driftlog.solver.extremes import volume_sum


def test_volume_sum_is_the_correctly_rounded_sum_of_the_products():
    rng = np.random.default_rng(5)
    for n in (1, 10, 46_691, 200_000):
        # depths from films to tens of metres, areas from 1 to 1e4 m2: terms over 10 decades
        h = rng.uniform(0.0, 1.0, n) ** 6 * 60.0
        a = 10.0 ** rng.uniform(0.0, 4.0, n)
        exact = math.fsum((h * a).tolist())
        got = volume_sum(h, a)
        assert abs(got - exact) <= 2 * math.ulp(exact), (n, got, exact)


def test_volume_sum_keeps_what_naive_summation_loses():
    # one large volume and many small ones: a plain left-to-right sum drops every small term
    h = np.array([1e16] + [1.0] * 1000 + [-1e16])
    a = np.ones_like(h)
    assert volume_sum(h, a) == 1000.0
    plain = 0.0
    for x in h:  # what a plain left-to-right sum gives
        plain += x
    assert plain == 0.0
