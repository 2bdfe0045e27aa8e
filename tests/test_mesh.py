import netCDF4
import numpy as np
import pytest

from driftlog.errors import MeshError
from driftlog.mesh import Mesh, read_mesh, read_ugrid_mesh
from driftlog.mesher import channel_mesh, circle, polygon_mesh


def test_regular_grid_topology():
    m = Mesh.regular_grid(5, 3, 2.0, 1.0, x0=10.0)
    assert m.n_faces == 15 and m.n_nodes == 24
    assert m.n_edges == 5 * 4 + 6 * 3  # horizontal + vertical edges
    assert m.boundary_edges.size == 2 * (5 + 3)
    np.testing.assert_allclose(m.face_area, 2.0)
    np.testing.assert_allclose(m.face_x[:5], 11.0 + 2.0 * np.arange(5))
    np.testing.assert_allclose(m.face_inradius, 2 * 2.0 / 6.0)
    # neighbours: interior face 6 (i=1, j=1) touches 5, 7, 1, 11
    assert sorted(m.face_neighbours[6]) == [1, 5, 7, 11]
    # edge normals point out of edge_faces[:, 0]
    e = np.arange(m.n_edges)
    f0 = m.edge_faces[:, 0]
    out = ((m.edge_x - m.face_x[f0]) * m.edge_normal[:, 0]
           + (m.edge_y - m.face_y[f0]) * m.edge_normal[:, 1])
    assert np.all(out[e] > 0)


def test_triangle_geometry_exact():
    # 3-4-5 right triangle: area 6, inradius 1, centroid (4/3, 1)
    m = Mesh([0, 4, 0], [0, 0, 3], [[0, 1, 2]])
    assert m.face_area[0] == pytest.approx(6.0)
    assert m.face_inradius[0] == pytest.approx(1.0)
    assert (m.face_x[0], m.face_y[0]) == pytest.approx((4 / 3, 1.0))


def test_clockwise_faces_are_reversed():
    m = Mesh([0, 1, 1, 0], [0, 0, 1, 1], [[0, 2, 1, -1], [0, 2, 3, -1]], repair=True)
    assert m.n_reversed == 1
    assert np.all(m.face_area > 0)
    with pytest.raises(MeshError, match="clockwise"):
        Mesh([0, 1, 1, 0], [0, 0, 1, 1], [[0, 3, 2, 1]], repair=False)


@pytest.mark.parametrize("faces,match", [
    ([[0, 1, 2]], "degenerate"),          # collinear
    ([[0, 1, 1]], "degenerate"),          # repeated node
    ([[0, 1, 7]], "beyond"),              # node out of range
    ([[0, 1, -1]], "fewer than 3"),
])
def test_bad_faces(faces, match):
    with pytest.raises(MeshError, match=match):
        Mesh([0, 1, 2, 0], [0, 0, 0, 1], faces)


def test_nonconvex_quad_is_an_error():
    with pytest.raises(MeshError, match="non-convex"):
        Mesh([0, 2, 1, 0], [0, 0, 0.3, 2], [[0, 1, 2, 3]])


def _honeycomb():
    """Seven regular hexagons (a centre and its ring), nodes shared, plus an octagon beside."""
    centres = [(0.0, 0.0)] + [(np.sqrt(3) * np.cos(np.pi / 6 + k * np.pi / 3),
                                np.sqrt(3) * np.sin(np.pi / 6 + k * np.pi / 3)) for k in range(6)]
    key, xs, ys, faces = {}, [], [], []
    for cx, cy in centres:
        face = []
        for j in range(6):
            px, py = cx + np.cos(j * np.pi / 3), cy + np.sin(j * np.pi / 3)
            k = (round(px, 9), round(py, 9))
            if k not in key:
                key[k] = len(xs)
                xs.append(px)
                ys.append(py)
            face.append(key[k])
        faces.append(face + [-1, -1])
    # a regular octagon far to the right, given clockwise (repaired)
    n0 = len(xs)
    ang = np.arange(8) * np.pi / 4
    xs += list(10.0 + np.cos(ang))
    ys += list(np.sin(ang))
    faces.append(list(range(n0 + 7, n0 - 1, -1)))
    return np.array(xs), np.array(ys), faces


def test_polygons_up_to_eight_sides():
    from driftlog.locate import brute_force_locate

    x, y, faces = _honeycomb()
    m = Mesh(x, y, faces)
    assert m.n_reversed == 1
    assert m.face_n.tolist() == [6] * 7 + [8]
    np.testing.assert_allclose(m.face_area[:7], 1.5 * np.sqrt(3), rtol=1e-14)
    assert m.face_area[7] == pytest.approx(2 * np.sqrt(2), rel=1e-14)
    np.testing.assert_allclose(m.face_x[7], 10.0, atol=1e-14)
    # the centre hexagon has six neighbours; 6 + 6 * 3 + 8 boundary edges
    assert sorted(m.face_neighbours[0].tolist()) == [-1, -1] + list(range(1, 7))
    assert m.boundary_edges.size == 6 * 3 + 8
    rng = np.random.default_rng(3)
    px, py = rng.uniform(-3, 11, 4000), rng.uniform(-3, 3, 4000)
    got = m.locate(px, py)
    count, first = brute_force_locate(px, py, m.face_nodes, m.face_n, m.node_x, m.node_y)
    assert count.max() == 1
    np.testing.assert_array_equal(got, first)
    assert np.sum(got >= 0) > 500
    assert "larger polygons" in repr(m)


def test_nonconvex_polygon_is_an_error():
    # a pentagon with a reflex node (dent at node 3)
    with pytest.raises(MeshError, match="non-convex polygons"):
        Mesh([0, 2, 2, 1, 0], [0, 0, 2, 1.0, 2], [[0, 1, 2, 3, 4]])
    # a collinear node in a hexagon is not strictly convex either
    with pytest.raises(MeshError, match="non-convex"):
        Mesh([0, 1, 2, 2, 1, 0], [0, 0, 0, 2, 3, 2], [[0, 1, 2, 3, 4, 5]])


def test_malpasset_loads(malpasset_mesh):
    m = malpasset_mesh
    assert m.n_faces == 46691 and m.n_nodes == 24173
    assert m.node_z is not None
    assert np.all(m.face_area > 0)
    # Euler characteristic of a disc: V - E + F = 1 (no holes in the valley mesh)
    assert m.n_nodes - m.n_edges + m.n_faces == 1
    assert m.boundary_edges.size == 1653  # the file's boundary segments


def _write_ugrid(path, x, y, faces, start_index, fill, z=None, faces_first=True):
    with netCDF4.Dataset(path, "w") as ds:
        ds.createDimension("nNodes", len(x))
        ds.createDimension("nFaces", len(faces))
        ds.createDimension("nMax", np.shape(faces)[1])
        t = ds.createVariable("mesh2d", "i4")
        t.cf_role = "mesh_topology"
        t.topology_dimension = 2
        t.node_coordinates = "mesh2d_node_x mesh2d_node_y"
        t.face_node_connectivity = "mesh2d_face_nodes"
        t.face_dimension = "nFaces"
        ds.createVariable("mesh2d_node_x", "f8", ("nNodes",))[:] = x
        ds.createVariable("mesh2d_node_y", "f8", ("nNodes",))[:] = y
        dims = ("nFaces", "nMax") if faces_first else ("nMax", "nFaces")
        v = ds.createVariable("mesh2d_face_nodes", "i4", dims, fill_value=fill)
        v.start_index = start_index
        v[:] = np.asarray(faces) if faces_first else np.asarray(faces).T
        if z is not None:
            zv = ds.createVariable("mesh2d_node_z", "f8", ("nNodes",))
            zv.location = "node"
            zv[:] = z


@pytest.mark.parametrize("start,fill,faces_first", [(0, -1, True), (1, -999, True),
                                                   (1, -2147483647, False)])
def test_ugrid_start_index_and_fill(tmp_path, start, fill, faces_first):
    x = [0, 1, 2, 0, 1, 2]
    y = [0, 0, 0, 1, 1, 1]
    faces = np.array([[0, 1, 4, 3], [1, 2, 5, fill - start]]) + start
    p = tmp_path / "m.nc"
    _write_ugrid(p, x, y, faces, start, fill, z=np.arange(6.0), faces_first=faces_first)
    m = read_ugrid_mesh(p)
    assert m.n_faces == 2 and list(m.face_n) == [4, 3]
    assert m.face_area.sum() == pytest.approx(1.5)
    np.testing.assert_allclose(m.node_z, np.arange(6.0))


def test_ugrid_errors(tmp_path):
    p = tmp_path / "bad.nc"
    p.write_bytes(b"CDF\x01 truncated")
    with pytest.raises(MeshError, match="cannot be read .truncated or corrupt"):
        read_mesh(p)
    with netCDF4.Dataset(tmp_path / "notopo.nc", "w") as ds:
        ds.createDimension("n", 3)
        ds.createVariable("x", "f8", ("n",))
    with pytest.raises(MeshError, match="mesh topology"):
        read_mesh(tmp_path / "notopo.nc")
    with pytest.raises(MeshError, match="not found"):
        read_mesh(tmp_path / "missing.nc")


def test_meshio_reader(tmp_path):
    import meshio

    pts = np.array([[0, 0, 1.0], [1, 0, 2.0], [1, 1, 3.0], [0, 1, 4.0], [2, 0, 5.0]])
    cells = [("quad", np.array([[0, 1, 2, 3]])), ("triangle", np.array([[1, 4, 2]]))]
    meshio.write(tmp_path / "m.vtu", meshio.Mesh(pts, cells))
    m = read_mesh(tmp_path / "m.vtu")
    assert m.n_faces == 2 and sorted(m.face_n) == [3, 4]
    np.testing.assert_allclose(m.node_z, pts[:, 2])
    meshio.write(tmp_path / "t.vtu", meshio.Mesh(pts, [("tetra", np.array([[0, 1, 2, 4]]))]))
    with pytest.raises(MeshError, match="unsupported element types.*tetra"):
        read_mesh(tmp_path / "t.vtu")


def test_tagging_and_segments():
    m = Mesh.regular_grid(4, 2, 1.0)
    assert m.tag_boundary("inflow", lambda x, y: x < 1e-9) == 2
    assert m.tag_boundary("outflow", (4, 0, 4, 2)) == 2
    assert m.edges_with_tag("wall").size == 8
    seg = m.boundary_segments(["inflow"])
    np.testing.assert_allclose(seg[:, [0, 2]], 0.0)


def test_node_interpolator_exact_for_linear_fields(mixed_mesh, malpasset_mesh):
    for m in (mixed_mesh, malpasset_mesh):
        P = m.node_interpolator()
        f = 2.0 - 0.5 * m.face_x + 0.25 * m.face_y
        exact = 2.0 - 0.5 * m.node_x + 0.25 * m.node_y
        assert np.max(np.abs(P @ f - exact)) < 1e-9 * np.abs(exact).max()


def test_channel_mesher_with_piers():
    piers = [circle((500, 45), 15, 5.0), circle((500, 125), 15, 5.0)]
    m = channel_mesh(1500, 170, 20.0, holes=piers)
    n = len(piers[0])
    area = 1500 * 170 - 2 * (0.5 * n * 15 ** 2 * np.sin(2 * np.pi / n))
    assert m.face_area.sum() == pytest.approx(area, rel=1e-9)
    inflow = m.boundary_segments(["inflow"])
    np.testing.assert_allclose(inflow[:, [0, 2]], 0.0)
    length = np.hypot(inflow[:, 2] - inflow[:, 0], inflow[:, 3] - inflow[:, 1]).sum()
    assert length == pytest.approx(170)
    # pier walls are tagged wall and lie on the circles
    walls = m.boundary_segments(["wall"])
    r = np.hypot(walls[:, 0] - 500, walls[:, 1] - 45)
    assert np.sum(np.abs(r - 15) < 1e-9) == n
    assert m.locate([500.0], [45.0])[0] == -1  # inside a pier: outside the mesh
    with pytest.raises(MeshError):
        polygon_mesh([[0, 0], [1, 0]], 0.1)


@pytest.mark.parametrize("cell", [0.05, 0.0125, 0.002])
def test_small_cells_get_their_size(cell):
    # the area switch must not be written in exponent notation (Triangle would read
    # "a6.8e-05" as area 6.8 and the -e switch): the mesh refines with the cell size
    m = polygon_mesh([[0, 0], [40 * cell, 0], [40 * cell, 8 * cell], [0, 8 * cell]], cell)
    assert m.face_area.max() <= np.sqrt(3) / 4 * cell ** 2 * (1 + 1e-9)
    assert m.n_faces > 40 * 8 * 2
