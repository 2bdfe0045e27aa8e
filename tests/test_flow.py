import numpy as np
import pytest

from driftlog.analytic import FreeVortex, SolidBodyRotation, UniformFlow, on_mesh
from driftlog.errors import FlowDomainError, FlowFileError
from driftlog.flow import DRY, OUTSIDE, WET, MeshFlowField
from driftlog.mesh import Mesh


def _linear_field(mesh, times):
    """h, u, v linear in x, y and t, on faces."""
    h, hu, hv = [], [], []
    for t in times:
        hh = 2.0 + 0.1 * mesh.face_x - 0.05 * mesh.face_y + 0.01 * t
        uu = 0.3 + 0.2 * mesh.face_x + 0.1 * mesh.face_y - 0.02 * t
        vv = -0.1 + 0.05 * mesh.face_x - 0.3 * mesh.face_y + 0.03 * t
        h.append(hh), hu.append(hh * uu), hv.append(hh * vv)
    return MeshFlowField.from_arrays(mesh, np.zeros(mesh.n_faces), times, h, hu, hv)


def test_mesh_sampling_reproduces_linear_fields(mixed_mesh, rng):
    f = _linear_field(mixed_mesh, [0.0, 10.0])
    x = rng.uniform(0, 6, 2000)
    y = rng.uniform(0, 4, 2000)
    t = 3.7
    s = f.sample(x, y, t)
    assert np.all(s.flag == WET)
    np.testing.assert_allclose(s.h, 2.0 + 0.1 * x - 0.05 * y + 0.01 * t, atol=1e-12)
    np.testing.assert_allclose(s.u, 0.3 + 0.2 * x + 0.1 * y - 0.02 * t, atol=1e-12)
    np.testing.assert_allclose(s.v, -0.1 + 0.05 * x - 0.3 * y + 0.03 * t, atol=1e-12)
    np.testing.assert_allclose(s.jacobian,
                               np.broadcast_to([[0.2, 0.1], [0.05, -0.3]], (x.size, 2, 2)),
                               atol=1e-11)
    np.testing.assert_allclose(s.dudt, np.broadcast_to([-0.02, 0.03], (x.size, 2)), atol=1e-12)
    np.testing.assert_allclose(s.grad_eta, np.broadcast_to([0.1, -0.05], (x.size, 2)), atol=1e-12)
    np.testing.assert_allclose(s.omega, 0.5 * (0.05 - 0.1), atol=1e-12)


def test_sampling_is_continuous_across_edges(malpasset_mesh, rng):
    f = on_mesh(FreeVortex(5000.0, center=(8000, 4000), core_radius=300), malpasset_mesh)
    e = rng.choice(np.flatnonzero(malpasset_mesh.edge_faces[:, 1] >= 0), 500)
    n = malpasset_mesh.edge_normal[e]
    eps = 1e-7
    xm, ym = malpasset_mesh.edge_x[e], malpasset_mesh.edge_y[e]
    a = f.sample(xm - eps * n[:, 0], ym - eps * n[:, 1], 0.0)
    b = f.sample(xm + eps * n[:, 0], ym + eps * n[:, 1], 0.0)
    assert np.max(np.abs(a.u - b.u)) < 1e-6
    assert np.all(a.face != b.face)  # the two samples are on either side of the edge
    # the recovered velocity gradient is continuous too; the P1 interpolant's is not
    assert np.max(np.abs(a.jacobian - b.jacobian)) < 1e-6
    f.gradient = "p1"
    f._snap.clear()
    f._pair = None
    a = f.sample(xm - eps * n[:, 0], ym - eps * n[:, 1], 0.0)
    b = f.sample(xm + eps * n[:, 0], ym + eps * n[:, 1], 0.0)
    assert np.max(np.abs(a.jacobian - b.jacobian)) > 1e-4


def test_time_interpolation_and_bounds(mixed_mesh):
    f = _linear_field(mixed_mesh, [0.0, 10.0, 20.0])
    s = f.sample([1.0], [1.0], 15.0)
    assert s.h[0] == pytest.approx(2.0 + 0.1 - 0.05 + 0.15)
    assert f.time_span == (0.0, 20.0)
    with pytest.raises(FlowDomainError, match="outside the flow's span"):
        f.sample([1.0], [1.0], 25.0)
    # arrays of times spanning several intervals
    s = f.sample([1.0, 1.0, 1.0], [1.0, 1.0, 1.0], [0.0, 12.0, 20.0])
    np.testing.assert_allclose(s.h, 2.05 + 0.01 * np.array([0.0, 12.0, 20.0]))


def test_only_two_snapshots_held(mixed_mesh):
    f = _linear_field(mixed_mesh, np.arange(10.0))
    for t in np.linspace(0, 9, 37):
        f.sample([2.0], [2.0], t)
        assert len(f._snap) <= 2


def test_dry_faces_no_division_by_zero(mixed_mesh):
    m = mixed_mesh
    h = np.where(m.face_x > 3, 0.0, 1.0)
    hu = np.where(m.face_x > 3, 0.0, 0.5)
    f = MeshFlowField.from_arrays(m, np.zeros(m.n_faces), [0.0], [h], [hu], [hu * 0])
    with np.errstate(all="raise"):
        s = f.sample([1.0, 5.5, 100.0], [1.0, 2.0, 1.0], 0.0)
    assert list(s.flag) == [WET, DRY, OUTSIDE]
    assert np.all(np.isfinite(s.values))
    assert s.u[1] == 0.0


@pytest.mark.parametrize("bad,match", [(np.nan, "non-finite"), (-1.0, "negative depth")])
def test_bad_snapshot_values(mixed_mesh, bad, match):
    m = mixed_mesh
    h = np.ones(m.n_faces)
    h[3] = bad
    f = MeshFlowField.from_arrays(m, np.zeros(m.n_faces), [0.0], [h], [h * 0], [h * 0])
    with pytest.raises(FlowFileError, match=match):
        f.sample([1.0], [1.0], 0.0)


def test_times_must_increase(mixed_mesh):
    m = mixed_mesh
    z = np.zeros((2, m.n_faces))
    with pytest.raises(FlowFileError, match="not increasing"):
        MeshFlowField.from_arrays(m, np.zeros(m.n_faces), [1.0, 1.0], z + 1, z, z)
    with pytest.raises(FlowFileError, match="2 snapshots for 3 times"):
        MeshFlowField.from_arrays(m, np.zeros(m.n_faces), [0.0, 1.0, 2.0], z + 1, z, z)


def _fd_check(field, x, y, t, eps=1e-5):
    s = field.sample(x, y, t)
    sx1, sx0 = field.sample(x + eps, y, t), field.sample(x - eps, y, t)
    sy1, sy0 = field.sample(x, y + eps, t), field.sample(x, y - eps, t)
    st1, st0 = field.sample(x, y, t + eps), field.sample(x, y, t - eps)
    J = np.stack([np.stack([(sx1.u - sx0.u), (sy1.u - sy0.u)], -1),
                  np.stack([(sx1.v - sx0.v), (sy1.v - sy0.v)], -1)], 1) / (2 * eps)
    np.testing.assert_allclose(s.jacobian, J, atol=1e-7)
    np.testing.assert_allclose(s.dudt, np.stack([st1.u - st0.u, st1.v - st0.v], -1) / (2 * eps),
                               atol=1e-7)
    np.testing.assert_allclose(s.grad_eta, np.stack([sx1.eta - sx0.eta, sy1.eta - sy0.eta], -1)
                               / (2 * eps), atol=1e-7)
    return s


@pytest.mark.parametrize("field", [UniformFlow(0.5, -0.2, acceleration=(0.01, 0.02)),
                                   SolidBodyRotation(0.1, center=(1.0, 2.0)),
                                   FreeVortex(3.0, center=(-1.0, 0.5), core_radius=0.5)])
def test_analytic_gradients(field, rng):
    x, y = rng.uniform(-4, 4, 50), rng.uniform(-4, 4, 50)
    s = _fd_check(field, x, y, 2.0)
    # the surface balances the steady (advective) acceleration: g grad(eta) = -(U.grad)U
    adv = np.einsum("nij,nj->ni", s.jacobian, np.stack([s.u, s.v], -1))
    np.testing.assert_allclose(9.81 * s.grad_eta, -adv, atol=1e-10)


def test_sloping_uniform_flow():
    s = UniformFlow(1.0, 0.0, surface_slope=(-1e-3, 0.0)).sample([0.0, 100.0], [0.0, 0.0], 0.0)
    np.testing.assert_allclose(s.grad_eta[:, 0], -1e-3)
    assert s.eta[1] - s.eta[0] == pytest.approx(-0.1)


def test_free_vortex_exact_values():
    f = FreeVortex(2 * np.pi * 3.0)
    s = f.sample([2.0, 0.0], [0.0, -3.0], 0.0)
    np.testing.assert_allclose(s.v[0], 1.5)  # u_theta = Gamma / (2 pi R)
    np.testing.assert_allclose(s.u[1], 1.0)
    np.testing.assert_allclose(s.omega, 0.0, atol=1e-15)


def test_solid_body_on_mesh_is_exact(malpasset_mesh, rng):
    sb = SolidBodyRotation(0.01, center=(8000, 4000))
    f = on_mesh(sb, malpasset_mesh, times=[0.0, 10.0])
    i = rng.integers(0, malpasset_mesh.n_faces, 5000)
    x = malpasset_mesh.face_x[i] + rng.normal(0, 3, i.size)
    y = malpasset_mesh.face_y[i] + rng.normal(0, 3, i.size)
    s, e = f.sample(x, y, 5.0), sb.sample(x, y, 5.0)
    ok = s.flag == WET
    assert ok.mean() > 0.95
    np.testing.assert_allclose(s.u[ok], e.u[ok], atol=1e-9)
    np.testing.assert_allclose(s.jacobian[ok], e.jacobian[ok], atol=1e-12)


def test_freeze_gives_steady_field(mixed_mesh):
    f = _linear_field(mixed_mesh, [0.0, 10.0]).freeze(5.0)
    assert f.steady
    a, b = f.sample([1.0], [1.0], -100.0), f.sample([1.0], [1.0], 1e6)
    np.testing.assert_array_equal(a.values, b.values)
    assert a.dudt[0, 0] == 0.0


def test_regular_grid_is_a_mesh(rng):
    g = Mesh.regular_grid(20, 10, 0.5)
    f = on_mesh(SolidBodyRotation(0.2, center=(5, 2.5)), g)
    x, y = rng.uniform(0, 10, 100), rng.uniform(0, 5, 100)
    np.testing.assert_allclose(f.sample(x, y, 0).u, -0.2 * (y - 2.5), atol=1e-12)
