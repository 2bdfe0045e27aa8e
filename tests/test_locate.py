import numpy as np
import pytest

from driftlog.locate import brute_force_locate
from driftlog.mesher import channel_mesh, circle


def _check(m, x, y, hint=None):
    f = m.locate(x, y, hint)
    count, _ = brute_force_locate(x, y, m.face_nodes, m.face_n, m.node_x, m.node_y)
    assert np.array_equal(f >= 0, count > 0), "inside/outside differs from brute force"
    from driftlog.locate import point_in_face

    for i in np.flatnonzero(f >= 0):
        assert point_in_face(x[i], y[i], f[i], m.face_nodes, m.face_n, m.node_x, m.node_y)
    return f


def _special_points(m, rng, n):
    """Vertices, edge midpoints and points a hair outside the boundary."""
    v = rng.integers(0, m.n_nodes, n)
    e = rng.integers(0, m.n_edges, n)
    t = rng.uniform(0, 1, n)
    a, b = m.edge_nodes[e, 0], m.edge_nodes[e, 1]
    ex = m.node_x[a] + t * (m.node_x[b] - m.node_x[a])
    ey = m.node_y[a] + t * (m.node_y[b] - m.node_y[a])
    be = m.boundary_edges[rng.integers(0, m.boundary_edges.size, n)]
    span = max(m.bounds[2] - m.bounds[0], m.bounds[3] - m.bounds[1])
    ox = m.edge_x[be] + 1e-6 * span * m.edge_normal[be, 0]
    oy = m.edge_y[be] + 1e-6 * span * m.edge_normal[be, 1]
    return np.concatenate([m.node_x[v], ex, ox]), np.concatenate([m.node_y[v], ey, oy])


@pytest.mark.parametrize("which", ["mixed", "channel", "malpasset"])
def test_locate_matches_brute_force(which, mixed_mesh, rng, request):
    if which == "mixed":
        m = mixed_mesh
    elif which == "channel":
        m = channel_mesh(100, 20, 2.0, holes=[circle((50, 10), 4, 1.0)])
    else:
        m = request.getfixturevalue("malpasset_mesh")
    x0, y0, x1, y1 = m.bounds
    n = 3000
    x = rng.uniform(x0 - 0.1 * (x1 - x0), x1 + 0.1 * (x1 - x0), n)
    y = rng.uniform(y0 - 0.1 * (y1 - y0), y1 + 0.1 * (y1 - y0), n)
    sx, sy = _special_points(m, rng, 300)
    x, y = np.concatenate([x, sx, [np.nan]]), np.concatenate([y, sy, [0.0]])
    f = _check(m, x, y)
    assert f[-1] == -1  # NaN is outside
    # warm: hints from a random face, and from the previous position after a small move
    _check(m, x, y, hint=rng.integers(0, m.n_faces, x.size))
    step = 0.3 * np.median(m.face_inradius)
    _check(m, x + rng.normal(0, step, x.size), y + rng.normal(0, step, x.size), hint=f)


def test_outside_points_far_away(mixed_mesh):
    f = mixed_mesh.locate([-1e9, 1e9, 3.0], [0.0, 0.0, 1e9])
    assert np.all(f == -1)
