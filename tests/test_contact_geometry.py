"""Narrow and broad phase: exact against independent formulas and brute force."""

import numpy as np
import pytest

from driftlog.contact.broadphase import StaticGrid, brute_pairs, grid_pairs, sweep_pairs
from driftlog.contact.geometry import capsule_gap, segment_closest_points


def _point_segment(p, a, b):
    d = b - a
    dd = d @ d
    t = 0.0 if dd == 0 else np.clip((p - a) @ d / dd, 0, 1)
    return np.linalg.norm(p - (a + t * d))


def _segments_intersect(a, b, c, d):
    def orient(p, q, r):
        return np.sign((q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0]))
    return orient(a, b, c) * orient(a, b, d) < 0 and orient(c, d, a) * orient(c, d, b) < 0


def _reference_distance(a, b, c, d):
    """Segment distance: 0 if they cross, else the least endpoint-to-segment distance."""
    if _segments_intersect(a, b, c, d):
        return 0.0
    return min(_point_segment(a, c, d), _point_segment(b, c, d), _point_segment(c, a, b),
               _point_segment(d, a, b))


def _random_segments(rng, n):
    P = rng.uniform(-1, 1, (n, 4, 2))
    # a share of degenerate (points) and parallel pairs, the hard cases
    P[: n // 10, 1] = P[: n // 10, 0]
    k = slice(n // 10, n // 5)
    P[k, 3] = P[k, 2] + (P[k, 1] - P[k, 0]) * rng.uniform(-2, 2, (n // 10, 1))
    return P


def test_segment_distance_matches_reference(rng):
    P = _random_segments(rng, 4000)
    out = np.empty(5)
    for a, b, c, d in P:
        s, t = segment_closest_points(*a, *b, *c, *d)
        p1, p2 = a + s * (b - a), c + t * (d - c)
        ref = _reference_distance(a, b, c, d)
        assert abs(np.linalg.norm(p1 - p2) - ref) < 1e-12
        gap = capsule_gap(*a, *b, 0.05, *c, *d, 0.02, out)
        if ref > 1e-9:
            assert abs(gap - (ref - 0.07)) < 1e-12
            # the normal is the unit vector between the closest points, from 2 to 1
            assert np.allclose(out[1:3], (p1 - p2) / ref, atol=1e-9)


def test_parallel_overlap_contact_at_middle():
    out = np.empty(5)
    # side by side logs overlapping over x in [0.5, 1]: contact point at x = 0.75
    gap = capsule_gap(0.0, 0.0, 1.0, 0.0, 0.1, 0.5, 0.25, 1.5, 0.25, 0.1, out)
    assert gap == pytest.approx(0.05, abs=1e-15)
    assert out[1:3] == pytest.approx([0.0, -1.0])
    assert out[3:5] == pytest.approx([0.75, 0.125])


def test_crossing_axes_depth_is_least_translation(rng):
    """Crossing axes: depth = min over directions of the support of the difference set."""
    phi = np.linspace(0, 2 * np.pi, 20001)[:-1]
    dirs = np.column_stack([np.cos(phi), np.sin(phi)])
    out = np.empty(5)
    n_cross = 0
    for _ in range(60):
        a, b, c, d = rng.uniform(-1, 1, (4, 2))
        if not _segments_intersect(a, b, c, d):
            continue
        n_cross += 1
        r1, r2 = 0.03, 0.07
        gap = capsule_gap(*a, *b, r1, *c, *d, r2, out)
        A, B = np.array([a, b]), np.array([c, d])
        # translating body 1 by s n separates the axes when s >= max(B.n) - min(A.n)
        s = (B @ dirs.T).max(axis=0) - (A @ dirs.T).min(axis=0)
        depth = s.min()
        # the sampled support has a kink at its minimum: first-order error in the spacing
        got = -gap - r1 - r2
        assert depth - 1e-3 < got <= depth + 1e-12
        # moving body 1 along the normal by the depth separates the axes exactly
        shift = (got + 1e-9) * out[1:3]
        assert not _segments_intersect(a + shift, b + shift, c, d)
        assert _segments_intersect(a + 0.999 * shift, b + 0.999 * shift, c, d)
    assert n_cross > 10


def test_capsule_circle_and_segment_analytic():
    out = np.empty(5)
    # log along x from (-1, 0) to (1, 0), r = 0.1; pier at (0.5, 1), radius 0.4: gap 0.5
    g = capsule_gap(-1, 0, 1, 0, 0.1, 0.5, 1.0, 0.5, 1.0, 0.4, out)
    assert g == pytest.approx(0.5)
    assert out[1:3] == pytest.approx([0.0, -1.0])
    assert out[3:5] == pytest.approx([0.5, 0.35])  # middle of the gap
    # pier beyond the log's end: the normal points from the pier centre to the log end
    g = capsule_gap(-1, 0, 1, 0, 0.1, 4.0, 4.0, 4.0, 4.0, 1.0, out)
    assert g == pytest.approx(5.0 - 1.1)
    assert out[1:3] == pytest.approx([-0.6, -0.8])
    # wall (zero radius) under a tilted log: the lower end is closest
    th = 0.3
    a = np.array([-np.cos(th), -np.sin(th)]) + [0, 2]
    b = np.array([np.cos(th), np.sin(th)]) + [0, 2]
    g = capsule_gap(*a, *b, 0.1, -10, 0, 10, 0, 0.0, out)
    assert g == pytest.approx(2 - np.sin(th) - 0.1)
    assert out[1:3] == pytest.approx([0.0, 1.0])
    # wall crossing the log's axis: depth to push it back above the wall
    g = capsule_gap(-1, -0.2, 1, 0.5, 0.1, -10, 0, 10, 0, 0.0, out)
    assert g == pytest.approx(-0.2 - 0.1)
    assert out[1:3] == pytest.approx([0.0, 1.0])


def _boxes(rng, n, spread):
    x, y = rng.uniform(-spread, spread, (2, n))
    ex, ey = rng.uniform(0.01, 0.6, (2, n))
    return x, y, ex, ey


@pytest.mark.parametrize("n,spread", [(2, 1.0), (300, 3.0), (3000, 40.0), (3000, 1e5)])
def test_grid_pairs_equal_brute_force(rng, n, spread):
    x, y, ex, ey = _boxes(rng, n, spread)
    g = grid_pairs(x, y, ex, ey)
    b = brute_pairs(x, y, ex, ey)
    assert len(g) == len(np.unique(g, axis=0))  # never twice
    assert set(map(tuple, g)) == set(map(tuple, b))


@pytest.mark.parametrize("n,sx,sy", [(2, 1.0, 1.0), (300, 3.0, 3.0), (3000, 400.0, 5.0),
                                      (3000, 5.0, 400.0), (3000, 1e5, 1e5)])
def test_sweep_pairs_are_the_grid_pairs(rng, n, sx, sy):
    """``sweep_pairs``: the set of ``grid_pairs`` (each pair once, i < j), along either axis,
    boxes that exactly touch included, non-finite boxes left to the grid."""
    x, y = rng.uniform(-sx, sx, n), rng.uniform(-sy, sy, n)
    ex, ey = rng.uniform(0.01, 0.6, (2, n))
    if n > 2:  # boxes that touch exactly along x, along y, and at a corner: pairs
        x[0], y[0], ex[0], ey[0] = 1.0, 2.0, 0.5, 0.25  # exact binary fractions
        x[1], y[1], ex[1], ey[1] = x[0] + ex[0] + 0.25, y[0], 0.25, ey[0]
        x[2], y[2], ex[2], ey[2] = x[0], y[0] - ey[0] - 0.5, ex[0], 0.5
        x[3], y[3], ex[3], ey[3] = x[0] - ex[0] - 0.125, y[0] + ey[0] + 0.125, 0.125, 0.125
    s = sweep_pairs(x, y, ex, ey)
    g = grid_pairs(x, y, ex, ey)
    assert len(s) == len(np.unique(s, axis=0)) and np.all(s[:, 0] < s[:, 1])
    assert set(map(tuple, s.tolist())) == set(map(tuple, g.tolist()))
    if n > 2:
        assert {(0, 1), (0, 2), (0, 3)} <= set(map(tuple, s.tolist()))
    x[-1] = np.nan
    assert set(map(tuple, sweep_pairs(x, y, ex, ey).tolist())) == \
        set(map(tuple, grid_pairs(x, y, ex, ey).tolist()))


def test_sweep_pairs_with_lower_ends_a_round_off_apart():
    """Centres a round-off apart and boxes a metre long: the sweep's quantum is some 1e-22 m,
    so the boxes' quantised upper ends lie about 1e22 quanta out, beyond int64 (capped: a
    wrapped, negative cut would stop the sweep at once and find no pair)."""
    k = np.arange(4.0)
    x, y = 1.0 + k * 2.0 ** -40, 2.0 + k * 2.0 ** -41
    ex, ey = np.full(4, 1.0), np.full(4, 0.6)
    s = sweep_pairs(x, y, ex, ey)
    assert len(s) == 6  # every box on top of every other
    assert set(map(tuple, s.tolist())) == set(map(tuple, brute_pairs(x, y, ex, ey).tolist()))


def test_grid_pairs_parallel_kernel(rng):
    x, y, ex, ey = _boxes(rng, 5000, 30.0)  # above PARALLEL_MIN: the prange compilation
    assert set(map(tuple, grid_pairs(x, y, ex, ey))) == set(map(tuple, brute_pairs(x, y, ex, ey)))


def test_static_grid_equals_brute_force(rng):
    m = 400
    a = rng.uniform(-20, 20, (m, 2))
    b = a + rng.normal(0, 3, (m, 2)) * (rng.random((m, 1)) < 0.7)  # some circles (a == b)
    r = np.where(np.all(a == b, axis=1), rng.uniform(0.1, 1, m), 0.0)
    caps = np.column_stack([a, b, r])
    grid = StaticGrid(caps, 1.0)
    x, y, ex, ey = _boxes(rng, 2000, 25.0)
    got = grid.query(x, y, ex, ey)
    assert len(got) == len(np.unique(got, axis=0))
    lo = np.minimum(a, b) - r[:, None]
    hi = np.maximum(a, b) + r[:, None]
    ref = np.argwhere((np.abs(x[:, None] - 0.5 * (lo[:, 0] + hi[:, 0])) <= ex[:, None]
                       + 0.5 * (hi[:, 0] - lo[:, 0]))
                      & (np.abs(y[:, None] - 0.5 * (lo[:, 1] + hi[:, 1])) <= ey[:, None]
                         + 0.5 * (hi[:, 1] - lo[:, 1])))
    assert set(map(tuple, got)) == set(map(tuple, ref))
