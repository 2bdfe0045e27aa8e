"""Node-located flow data (TELEMAC style): sampled P1 on their own nodes, not via faces."""

import numpy as np
import pytest

from driftlog.errors import FlowFileError
from driftlog.flow import WET, InMemorySnapshots, MeshFlowField
from driftlog.nodal import face_mean_operator, node_gradient_operators


def _node_field(mesh, times, fun, bed=None, gradient="recovered"):
    h, hu, hv = [], [], []
    for t in times:
        hh, uu, vv = fun(mesh.node_x, mesh.node_y, t)
        h.append(hh), hu.append(hh * uu), hv.append(hh * vv)
    bed = np.zeros(mesh.n_nodes) if bed is None else bed
    return MeshFlowField.from_arrays(mesh, bed, times, h, hu, hv, location="node",
                                     gradient=gradient)


def _linear(x, y, t):
    return (2.0 + 0.1 * x - 0.05 * y + 0.01 * t, 0.3 + 0.2 * x + 0.1 * y - 0.02 * t,
            -0.1 + 0.05 * x - 0.3 * y + 0.03 * t)


def _wavy(x, y, t):
    return 1.5 + 0.3 * np.sin(x) * np.cos(y), 0.5 * np.cos(1.3 * x + t), 0.2 * np.sin(0.7 * y)


@pytest.mark.parametrize("gradient", ["recovered", "p1"])
def test_node_data_reproduce_linear_fields(mixed_mesh, rng, gradient):
    bed = -1.0 + 0.02 * mixed_mesh.node_x + 0.03 * mixed_mesh.node_y
    f = _node_field(mixed_mesh, [0.0, 10.0], _linear, bed=bed, gradient=gradient)
    x, y, t = rng.uniform(0, 6, 2000), rng.uniform(0, 4, 2000), 3.7
    s = f.sample(x, y, t)
    assert np.all(s.flag == WET)
    h, u, v = _linear(x, y, t)
    np.testing.assert_allclose(s.h, h, atol=1e-12)
    np.testing.assert_allclose(s.u, u, atol=1e-12)
    np.testing.assert_allclose(s.v, v, atol=1e-12)
    np.testing.assert_allclose(s.eta, h - 1.0 + 0.02 * x + 0.03 * y, atol=1e-12)
    np.testing.assert_allclose(s.dudt, np.broadcast_to([-0.02, 0.03], (x.size, 2)), atol=1e-12)
    np.testing.assert_allclose(s.jacobian, np.broadcast_to([[0.2, 0.1], [0.05, -0.3]],
                                                           (x.size, 2, 2)), atol=1e-11)
    np.testing.assert_allclose(s.grad_eta, np.broadcast_to([0.12, -0.02], (x.size, 2)),
                               atol=1e-11)


def test_node_values_are_used_as_they_are(mixed_mesh):
    """At a node the sample is that node's own value (a nonlinear field: no face fit)."""
    f = _node_field(mixed_mesh, [0.0, 1.0], _wavy)
    x, y = mixed_mesh.node_x, mixed_mesh.node_y
    # nudge the points inside the domain (boundary nodes lie on its edge)
    cx, cy = mixed_mesh.face_x.mean(), mixed_mesh.face_y.mean()
    px, py = x + 1e-12 * (cx - x), y + 1e-12 * (cy - y)
    s = f.sample(px, py, 0.0)
    h, u, v = _wavy(x, y, 0.0)
    np.testing.assert_allclose(s.h, h, atol=1e-10)
    np.testing.assert_allclose(s.u, u, atol=1e-10)
    np.testing.assert_allclose(s.v, v, atol=1e-10)
    # the same data averaged onto faces and recovered at nodes (the face path) differ
    A = face_mean_operator(mixed_mesh)
    hf = A @ (h * u)
    g = MeshFlowField.from_arrays(mixed_mesh, np.zeros(mixed_mesh.n_faces), [0.0], [A @ h],
                                  [hf], [A @ (h * v)])
    assert np.max(np.abs(g.sample(px, py, 0.0).u - u)) > 1e-2


def test_face_arrays_of_node_data_are_face_means(mixed_mesh):
    f = _node_field(mixed_mesh, [0.0, 1.0], _wavy, bed=np.linspace(0, 1, mixed_mesh.n_nodes))
    h, u, v = _wavy(mixed_mesh.node_x, mixed_mesh.node_y, 1.0)
    fh, fhu, fhv = f.read_snapshot(1)
    for k in range(mixed_mesh.n_faces):
        nodes = mixed_mesh.face_nodes[k, :mixed_mesh.face_n[k]]
        assert fh[k] == pytest.approx(h[nodes].mean(), rel=1e-14)
        assert fhu[k] == pytest.approx((h * u)[nodes].mean(), rel=1e-14)
        assert f.bed[k] == pytest.approx(f.node_bed[nodes].mean(), rel=1e-14)
    snap = f.snapshot(1)
    np.testing.assert_allclose(snap["eta"], fh + f.bed, rtol=1e-14)
    # read_source gives the node arrays themselves
    nh, nhu, _ = f.read_source(1)
    np.testing.assert_array_equal(nh, h)
    np.testing.assert_array_equal(nhu, h * u)


def test_gradient_operators_exact_for_linear(mixed_mesh):
    Gx, Gy = node_gradient_operators(mixed_mesh)
    q = 3.0 - 0.7 * mixed_mesh.node_x + 1.9 * mixed_mesh.node_y
    np.testing.assert_allclose(Gx @ q, -0.7, atol=1e-12)
    np.testing.assert_allclose(Gy @ q, 1.9, atol=1e-12)


def test_freeze_keeps_node_data(mixed_mesh, rng):
    f = _node_field(mixed_mesh, [0.0, 10.0], _wavy)
    g = f.freeze(4.0)
    assert g.location == "node" and g.steady
    x, y = rng.uniform(0.1, 5.9, 300), rng.uniform(0.1, 3.9, 300)
    a, b = f.sample(x, y, 4.0), g.sample(x, y, 123.0)
    np.testing.assert_allclose(b.values[:, :3], a.values[:, :3], atol=1e-13)


def test_dry_nodes_have_no_velocity(mixed_mesh):
    h = np.where(mixed_mesh.node_x < 2.0, 0.0, 1.0)
    u = np.full(mixed_mesh.n_nodes, 0.7)
    f = MeshFlowField.from_arrays(mixed_mesh, np.zeros(mixed_mesh.n_nodes), [0.0], [h],
                                  [h * u + (h == 0) * 5.0], [0 * h], location="node")
    s = f.sample([0.5, 4.5], [1.0, 1.0], 0.0)
    assert s.flag.tolist() == [1, 2]
    assert s.u[0] == 0.0 and s.u[1] == pytest.approx(0.7, rel=1e-14)


def test_node_columns_of_a_snapshot(mixed_mesh, rng):
    """A node snapshot's columns, read in one pass (``flow.node_columns``): h, hu / h (0 at
    and below the dry depth), hv / h, h + bed, bit for bit the numpy formulas; the gradient
    columns NaN until a reader asks for them, then the recovered gradients."""
    from driftlog.columns import NQ, Q_ETA, Q_H, Q_U, Q_UX, Q_V

    n = mixed_mesh.n_nodes
    h = rng.uniform(0.0, 2.0, n)
    h[::7] = 0.0
    h[1::7] = 1e-7  # below the default dry depth
    hu, hv = rng.normal(0, 1, n) * h, rng.normal(0, 1, n) * h
    bed = rng.uniform(-1, 1, n)
    f = MeshFlowField.from_arrays(mixed_mesh, bed, [0.0, 5.0], [h, h], [hu, hu], [hv, hv],
                                  location="node")
    wet = h > f.dry_depth
    assert not wet.all() and wet.any()
    entry = f._load(0, gradients=False)
    nodes = entry[3]
    assert nodes.shape == (n, NQ)
    safe = np.where(wet, h, 1.0)
    np.testing.assert_array_equal(nodes[:, Q_H], h)
    np.testing.assert_array_equal(nodes[:, Q_U], np.where(wet, hu / safe, 0.0))
    np.testing.assert_array_equal(nodes[:, Q_V], np.where(wet, hv / safe, 0.0))
    np.testing.assert_array_equal(nodes[:, Q_ETA], h + bed)
    assert np.isnan(nodes[:, Q_UX:]).all()
    f._load(0, gradients=True)
    g = MeshFlowField.from_arrays(mixed_mesh, bed, [0.0, 5.0], [h, h], [hu, hu], [hv, hv],
                                  location="node")
    np.testing.assert_array_equal(nodes, g._load(0)[3])
    assert np.isfinite(nodes).all()


def test_bad_node_data(mixed_mesh):
    with pytest.raises(FlowFileError, match="the mesh has .* nodes"):
        MeshFlowField.from_arrays(mixed_mesh, np.zeros(mixed_mesh.n_faces), [0.0],
                                  [np.ones(mixed_mesh.n_nodes)] * 1, [np.zeros(3)], [np.zeros(3)],
                                  location="node")
    src = InMemorySnapshots([0.0], [np.ones(mixed_mesh.n_faces)], [np.ones(mixed_mesh.n_faces)],
                            [np.ones(mixed_mesh.n_faces)], location="node")
    f = MeshFlowField(mixed_mesh, np.zeros(mixed_mesh.n_nodes), src)
    with pytest.raises(FlowFileError, match="h has shape .* nodes"):
        f.sample([1.0], [1.0], 0.0)
    src.location = "edge"
    with pytest.raises(FlowFileError, match="'face' or 'node'"):
        MeshFlowField(mixed_mesh, np.zeros(mixed_mesh.n_nodes), src)
