"""GridFlowField: bilinear sampling of regular grids, its derivatives, wet / dry, location."""

import numpy as np
import pytest

from driftlog.flow import DRY, OUTSIDE, WET
from driftlog.gridflow import GridFlowField

NX, NY, DX, DY, X0, Y0 = 7, 5, 20.0, 10.0, 100.0, -50.0
TIMES = np.array([0.0, 4.0, 10.0])


def bilinear_u(x, y, t):
    """A field in the bilinear space on every cell, linear in time."""
    return 0.3 + 0.01 * x - 0.02 * y + 2e-4 * x * y + 0.05 * t


def bilinear_v(x, y, t):
    return -0.1 + 0.003 * x + 0.004 * y - 1e-4 * x * y - 0.02 * t


def make_field(depth=None, bed=None):
    f = GridFlowField.from_arrays(NX, NY, DX, DY, X0, Y0, np.zeros(NX * NY), TIMES,
                                  np.zeros((3, NX * NY)), np.zeros((3, NX * NY)),
                                  np.zeros((3, NX * NY)))
    px, py = f.point_coordinates()
    h = np.stack([np.full(px.size, 2.0) if depth is None else depth(px, py, t) for t in TIMES])
    u = np.stack([bilinear_u(px, py, t) for t in TIMES])
    v = np.stack([bilinear_v(px, py, t) for t in TIMES])
    b = np.zeros(px.size) if bed is None else bed(px, py)
    return GridFlowField.from_arrays(NX, NY, DX, DY, X0, Y0, b, TIMES, h, h * u, h * v)


def inner_points(n, rng):
    """Points between the outermost cell centres (where the interpolant is bilinear)."""
    x = X0 + DX / 2 + (NX - 1) * DX * rng.random(n)
    y = Y0 + DY / 2 + (NY - 1) * DY * rng.random(n)
    return x, y


def test_bilinear_field_reproduced_exactly():
    """Values, gradient and dU/dt of a field bilinear in space and linear in time are exact."""
    f = make_field()
    x, y = inner_points(500, np.random.default_rng(1))
    for t in (0.0, 2.5, 4.0, 7.3, 10.0):
        s = f.sample(x, y, t)
        assert np.all(s.flag == WET)
        np.testing.assert_allclose(s.u, bilinear_u(x, y, t), atol=1e-12)
        np.testing.assert_allclose(s.v, bilinear_v(x, y, t), atol=1e-12)
        J = s.jacobian
        np.testing.assert_allclose(J[:, 0, 0], 0.01 + 2e-4 * y, atol=1e-12)
        np.testing.assert_allclose(J[:, 0, 1], -0.02 + 2e-4 * x, atol=1e-12)
        np.testing.assert_allclose(J[:, 1, 0], 0.003 - 1e-4 * y, atol=1e-12)
        np.testing.assert_allclose(J[:, 1, 1], 0.004 - 1e-4 * x, atol=1e-12)
        np.testing.assert_allclose(s.dudt[:, 0], 0.05, atol=1e-12)
        np.testing.assert_allclose(s.dudt[:, 1], -0.02, atol=1e-12)
        np.testing.assert_allclose(s.h, 2.0, atol=1e-12)


def test_gradient_is_the_derivative_of_the_interpolant():
    """Central differences of sampled values equal the sampled gradient everywhere (outer half
    cells included), on a field that is not bilinear; and dU/dt the time derivative."""
    rng = np.random.default_rng(2)
    f = make_field(depth=lambda x, y, t: 1.0 + 0.5 * np.sin(x / 30.0) * np.cos(y / 17.0))
    # random points over the whole domain, away from cell-centre lines (kinks of the interpolant)
    x = X0 + NX * DX * rng.random(400)
    y = Y0 + NY * DY * rng.random(400)
    fx = (x - X0) / DX - 0.5
    fy = (y - Y0) / DY - 0.5
    keep = (np.abs(fx - np.round(fx)) > 0.01) & (np.abs(fy - np.round(fy)) > 0.01)
    x, y = x[keep], y[keep]
    t, e = 5.5, 1e-4
    s = f.sample(x, y, t)
    for col, (gx, gy) in ((1, (5, 6)), (2, (7, 8)), (11, (9, 10))):
        def at(xx, yy, c=col):
            return f.sample(xx, yy, t).values[:, c]

        ddx = (at(x + e, y) - at(x - e, y)) / (2 * e)
        ddy = (at(x, y + e) - at(x, y - e)) / (2 * e)
        np.testing.assert_allclose(s.values[:, gx], ddx, atol=1e-8)
        np.testing.assert_allclose(s.values[:, gy], ddy, atol=1e-8)
    ddt = (f.sample(x, y, t + e).values[:, 1:3] - f.sample(x, y, t - e).values[:, 1:3]) / (2 * e)
    np.testing.assert_allclose(s.dudt, ddt, atol=1e-8)


def test_values_at_the_points_and_held_in_the_outer_half_cell():
    f = make_field()
    px, py = f.point_coordinates()
    s = f.sample(px, py, 4.0)
    np.testing.assert_allclose(s.u, bilinear_u(px, py, 4.0), atol=1e-12)
    # cell index hints: the cell holding each point (the centre of face k is point k)
    np.testing.assert_array_equal(s.face, np.arange(px.size))
    # west edge: the value of the outermost column, no slope across the edge
    y = Y0 + DY / 2 + (NY - 1) * DY * np.linspace(0, 1, 9)
    edge = f.sample(np.full(9, X0 + 0.1), y, 4.0)
    first = f.sample(np.full(9, X0 + DX / 2), y, 4.0)
    np.testing.assert_allclose(edge.u, first.u, atol=1e-12)
    np.testing.assert_allclose(edge.jacobian[:, 0, 0], 0.0, atol=1e-15)
    np.testing.assert_allclose(edge.jacobian[:, 0, 1], first.jacobian[:, 0, 1], atol=1e-12)


def test_outside_and_the_grid_edges():
    f = make_field()
    x = np.array([X0 - 0.01, X0 + NX * DX + 0.01, X0 + 5, X0 + 5, X0, X0 + NX * DX])
    y = np.array([Y0 + 5, Y0 + 5, Y0 - 0.01, Y0 + NY * DY + 0.01, Y0, Y0 + NY * DY])
    s = f.sample(x, y, 1.0)
    np.testing.assert_array_equal(s.flag, [OUTSIDE] * 4 + [WET, WET])
    np.testing.assert_array_equal(s.face[:4], -1)
    np.testing.assert_array_equal(s.face[4:], [0, NX * NY - 1])
    assert np.all(s.values[:4] == 0.0)


def test_dry_points_have_no_velocity_and_dry_samples_are_flagged():
    """A dry column (depth 0, say land read with fill = 'dry'): velocity 0 on its points, the
    velocity tapers bilinearly towards it, samples where the interpolated depth is below
    dry_depth are dry, and the water level is bed + depth."""
    i_dry = 3

    def depth(x, y, t):
        return np.where(np.isclose(x, X0 + DX * (i_dry + 0.5)), 0.0, 1.5)

    f = make_field(depth=depth, bed=lambda x, y: 0.01 * x)
    xd = X0 + DX * (i_dry + 0.5)
    y = np.full(3, Y0 + 2.2 * DY)
    s = f.sample(np.array([xd, xd - DX / 4, xd - DX]), y, 4.0)
    np.testing.assert_array_equal(s.flag, [DRY, WET, WET])
    assert s.u[0] == 0.0 and s.v[0] == 0.0
    np.testing.assert_allclose(s.h, [0.0, 0.375, 1.5])
    # a quarter of the way from the dry centre (u = 0, weight 3/4) to the wet one
    np.testing.assert_allclose(s.u[1], 0.25 * bilinear_u(xd - DX, y[1], 4.0), rtol=1e-12)
    np.testing.assert_allclose(s.eta, 0.01 * np.array([xd, xd - DX / 4, xd - DX]) + s.h,
                               atol=1e-12)


def test_freeze_keeps_the_grid_sampler():
    f = make_field()
    g = f.freeze(7.0)
    assert isinstance(g, GridFlowField) and g.steady
    x, y = inner_points(50, np.random.default_rng(3))
    np.testing.assert_allclose(g.sample(x, y, 123.0).u, f.sample(x, y, 7.0).u, atol=1e-12)


def test_bad_grid():
    from driftlog.errors import FlowFileError

    with pytest.raises(FlowFileError, match="nx, ny >= 1"):
        GridFlowField.from_arrays(0, 3, 1.0, 1.0, 0, 0, np.zeros(0), [0.0], np.zeros((1, 0)),
                                  np.zeros((1, 0)), np.zeros((1, 0)))


def test_node_layout_bilinear_on_the_hull_of_the_points():
    """Node-based values (the points are the cells' corners): exact for a bilinear field on
    the whole domain, which ends at the outermost points; the mesh's nodes are the points."""
    nx, ny, x0, y0 = 6, 4, 10.0, 20.0
    X, Y = np.meshgrid(x0 + DX * np.arange(nx), y0 + DY * np.arange(ny))
    px, py = X.ravel(), Y.ravel()
    h = np.stack([np.full(px.size, 1.5) for _ in TIMES])
    u = np.stack([bilinear_u(px, py, t) for t in TIMES])
    v = np.stack([bilinear_v(px, py, t) for t in TIMES])
    f = GridFlowField.from_arrays(nx, ny, DX, DY, x0, y0, 0.01 * px, TIMES, h, h * u, h * v,
                                  layout="node")
    np.testing.assert_allclose(f.mesh.node_x, px)
    np.testing.assert_allclose(f.mesh.node_y, py)
    assert f.mesh.n_faces == (nx - 1) * (ny - 1)
    np.testing.assert_allclose(f.point_coordinates()[0], px)
    rng = np.random.default_rng(4)
    x = x0 + (nx - 1) * DX * rng.random(300)
    y = y0 + (ny - 1) * DY * rng.random(300)
    for t in (0.0, 5.0, 10.0):
        s = f.sample(x, y, t)
        assert np.all(s.flag == WET)
        np.testing.assert_allclose(s.u, bilinear_u(x, y, t), atol=1e-12)
        np.testing.assert_allclose(s.v, bilinear_v(x, y, t), atol=1e-12)
        np.testing.assert_allclose(s.jacobian[:, 0, 1], -0.02 + 2e-4 * x, atol=1e-12)
        np.testing.assert_allclose(s.eta, 1.5 + 0.01 * x, atol=1e-12)
        np.testing.assert_array_equal(s.face, f.mesh.locate(x, y))
    out = f.sample(np.array([x0 - 0.01, x0 + 5.0]), np.array([y0 + 5.0, y0 - 0.01]), 1.0)
    np.testing.assert_array_equal(out.flag, [OUTSIDE, OUTSIDE])
    # face arrays: the mean of each cell's four corners; freeze keeps the layout
    np.testing.assert_allclose(f.snapshot(1)["h"], 1.5)
    g = f.freeze(7.0)
    assert g.layout == "node"
    np.testing.assert_allclose(g.sample(x, y, 0.0).u, f.sample(x, y, 7.0).u, atol=1e-12)


def test_cf_grid_node_layout_option(tmp_path):
    """cf_grid with [flow.options] layout = 'node': the domain is the coordinates' hull."""
    import netCDF4
    from driftlog.adapters import open_flow_source

    path = tmp_path / "g.nc"
    xs, ys = 100.0 + DX * np.arange(5), 50.0 + DY * np.arange(4)
    with netCDF4.Dataset(path, "w") as ds:
        for name, c in (("x", xs), ("y", ys)):
            ds.createDimension(name, c.size)
            var = ds.createVariable(name, "f8", (name,))
            var[:] = c
            var.units = "m"
        X, Y = np.meshgrid(xs, ys)
        for name, val in (("bed", 0.0 * X), ("depth", 1.0 + 0 * X), ("u", bilinear_u(X, Y, 0)),
                          ("v", bilinear_v(X, Y, 0))):
            ds.createVariable(name, "f8", ("y", "x"))[:] = val
    cell = open_flow_source("cf_grid", path)
    node = open_flow_source("cf_grid", path, layout="node")
    assert cell.grid[2:4] == (100.0 - DX / 2, 50.0 - DY / 2) and cell.layout == "cell"
    assert node.grid[2:4] == (100.0, 50.0) and node.mesh.n_nodes == 20
    x, y = np.array([101.0, 99.0]), np.array([51.0, 51.0])
    assert node.sample(x, y, 0.0).flag.tolist() == [WET, OUTSIDE]
    assert cell.sample(x, y, 0.0).flag.tolist() == [WET, WET]
    np.testing.assert_allclose(node.sample(x[:1], y[:1], 0.0).u, bilinear_u(x[:1], y[:1], 0),
                               atol=1e-12)


def test_contacts_and_land_on_a_grid():
    """Walls on a grid are its outer edges (the mesh's boundary, tags as on any mesh): a log
    pushed north bounces on y = 8 and leaves through the open east end.  Land (dry cells
    inside the grid) is not a wall: a log drifting into it grounds at the shore."""
    from driftlog.contact import ContactModel
    from driftlog.logs import LEFT, RESTING, STRANDED, Logs
    from driftlog.physics import PhysicsOptions
    from driftlog.scenario import load_scenario
    from driftlog.tracker import Tracker

    nx, ny = 30, 8
    n = nx * ny

    def grid(depth):
        h = np.tile(depth, (2, 1))
        return GridFlowField.from_arrays(nx, ny, 1.0, 1.0, 0.0, 0.0, np.zeros(n), [0.0, 100.0],
                                         h, h * 1.0, h * 0.3)

    open_water = grid(np.ones(n))
    mesh = open_water.mesh
    assert mesh.boundary_edges.size == 2 * (nx + ny)
    mesh.tag_boundary("outflow", (nx - 0.5, -1, nx + 1, ny + 1))
    scen = load_scenario({"contact": {"enabled": True, "walls": True, "restitution": 0.5}})
    model = ContactModel.from_sections(scen["contact"], scen["obstacles"], mesh=mesh)
    logs = Logs([3.0], [4.0], [0.0], length=1.0, radius=0.1, density=700.0)
    Tracker(open_water, logs, PhysicsOptions(), contact=model, t_end=60.0).run()
    hits = model.drain_hits()
    assert len(hits["time"]) >= 1 and np.all(np.abs(hits["y"] - ny) < 1e-3)
    assert logs.status[0] == LEFT
    # land: the cells east of x = 15 are dry (depth 0)
    px = np.tile(np.arange(nx) + 0.5, ny)
    land = grid(np.where(px > 15.0, 0.0, 1.0))
    logs = Logs([3.0], [2.0], [0.0], length=1.0, radius=0.1, density=700.0)
    Tracker(land, logs, PhysicsOptions(), t_end=60.0).run()
    assert logs.status[0] in (RESTING, STRANDED)  # grounded in the shallows
    assert 13.0 < logs.state[0, 0] < 16.0, logs.state[0, 0]  # at the shore, not on the land


def test_mesh_built_only_when_asked():
    """Sampling needs no mesh; walls, location and repr get the same mesh as regular_grid."""
    from driftlog.mesh import Mesh

    f = make_field()
    x, y = inner_points(20, np.random.default_rng(6))
    f.sample(x, y, 3.0)
    f.snapshot(2)
    assert not f.mesh.built
    assert f.mesh.n_faces == NX * NY and f.mesh.n_nodes == (NX + 1) * (NY + 1)
    ref = Mesh.regular_grid(NX, NY, DX, DY, x0=X0, y0=Y0)
    assert repr(f.mesh) == repr(ref)
    np.testing.assert_array_equal(f.mesh.face_nodes, ref.face_nodes)
    np.testing.assert_allclose(f.mesh.bounds, ref.bounds)
    assert not f.mesh.built
    np.testing.assert_allclose(f.mesh.boundary_segments(), ref.boundary_segments())
    assert f.mesh.built
    np.testing.assert_array_equal(f.mesh.locate(x, y), f.sample(x, y, 3.0).face)


def test_cf_grid_land_at_fill_values_keeps_a_finite_water_level(tmp_path):
    """A CF grid whose land cells are fill values everywhere (bed too), read with fill = 'dry':
    the land is dry, and the water level next to it is finite (the bed there is the nearest
    valid one), so the full model's free-surface slope is never NaN."""
    import netCDF4
    from driftlog.adapters import open_flow_source

    n = 6
    path = tmp_path / "land.nc"
    with netCDF4.Dataset(path, "w") as ds:
        for name in ("x", "y"):
            ds.createDimension(name, n)
            var = ds.createVariable(name, "f8", (name,))
            var[:] = np.arange(n) + 0.5
            var.units = "m"
        for name, val in (("bed", 0.2), ("depth", 1.0), ("u", 0.5), ("v", 0.0)):
            var = ds.createVariable(name, "f8", ("y", "x"), fill_value=-9999.0)
            if name == "bed":
                var.standard_name = "altitude"
            a = np.full((n, n), val)
            a[2:4, 2:4] = -9999.0
            var[:] = a
    f = open_flow_source("cf_grid", path, fill="dry")
    assert "4 bed cells at fill values" in f.attrs["import_notes"]
    np.testing.assert_allclose(f.bed, 0.2)
    rng = np.random.default_rng(7)
    s = f.sample(n * rng.random(500), n * rng.random(500), 0.0)
    assert np.all(np.isfinite(s.values))
    land = f.sample(np.array([3.0]), np.array([3.0]), 0.0)
    assert land.flag[0] == DRY and land.u[0] == 0.0
