"""Seams: coincident nodes of partitioned meshes are merged, so an internal seam is not a wall.

Partitioned D-Flow FM, ANUGA and HEC-RAS area meshes repeat the nodes along the lines where
their parts meet.  Read as they are, the edges along such a line have a face on one side only:
boundary edges, hence walls for the contact model (a log stops against the seam, 88 hits in
the report of issue 12), while the flow itself is continuous.  Readers merge nodes closer than
``SEAM_TOLERANCE`` (1e-6) times the shortest edge touching them; a real boundary (a slit, a
gap between parts) is kept.
"""

import netCDF4
import numpy as np
import pytest
from driftlog.adapters import open_flow_source

from driftlog.contact import ContactModel
from driftlog.logs import LEFT, Logs
from driftlog.mesh import SEAM_TOLERANCE, Mesh, merge_coincident_nodes, read_ugrid_mesh
from driftlog.physics import PhysicsOptions
from driftlog.scenario import load_scenario
from driftlog.tracker import Tracker

NX, NY, SEAM = 20, 6, 10  # cells of 1 m; the parts meet on x = SEAM


def seamed_grid(gap=0.0, jitter=0.0):
    """Quads of a 20 x 6 m channel in two parts whose nodes on x = 10 are repeated.

    ``gap``: the right part shifted east by that much (a real slit when it is not round-off);
    ``jitter``: the repeated nodes moved by up to that much (round-off of a partitioner).
    """
    rng = np.random.default_rng(0)
    xs, ys, faces = [], [], []
    for part, (i0, i1) in enumerate(((0, SEAM), (SEAM, NX))):
        base = sum(len(x) for x in xs)
        X, Y = np.meshgrid(np.arange(i0, i1 + 1, dtype=float), np.arange(NY + 1, dtype=float))
        if part == 1:
            X = X + gap
            X[:, 0] += jitter * rng.uniform(-1, 1, NY + 1)
            Y[:, 0] += jitter * rng.uniform(-1, 1, NY + 1)
        xs.append(X.ravel())
        ys.append(Y.ravel())
        w = i1 - i0 + 1
        nid = base + np.arange(X.size).reshape(NY + 1, w)
        faces.append(np.stack([nid[:-1, :-1], nid[:-1, 1:], nid[1:, 1:], nid[1:, :-1]],
                              axis=-1).reshape(-1, 4))
    return np.concatenate(xs), np.concatenate(ys), np.concatenate(faces)


def write_ugrid(path, x, y, faces, u=1.0, v=0.3, depth=1.0, times=(0.0, 100.0)):
    """A UGRID map file: the mesh and a uniform flow on its faces."""
    with netCDF4.Dataset(path, "w") as ds:
        ds.createDimension("nNodes", x.size)
        ds.createDimension("nFaces", len(faces))
        ds.createDimension("nMax", 4)
        ds.createDimension("time", None)
        m = ds.createVariable("mesh2d", "i4")
        m.cf_role, m.topology_dimension = "mesh_topology", 2
        m.node_coordinates = "mesh2d_node_x mesh2d_node_y"
        m.face_node_connectivity = "mesh2d_face_nodes"
        m.face_dimension = "nFaces"
        for nm, vals in (("mesh2d_node_x", x), ("mesh2d_node_y", y)):
            var = ds.createVariable(nm, "f8", ("nNodes",))
            var[:] = vals
            var.units = "m"
        fn = ds.createVariable("mesh2d_face_nodes", "i4", ("nFaces", "nMax"), fill_value=-1)
        fn.start_index = 0
        fn[:] = faces
        t = ds.createVariable("time", "f8", ("time",))
        t.units = "seconds since 2020-01-01"
        t[:] = times
        bl = ds.createVariable("mesh2d_flowelem_bl", "f8", ("nFaces",))
        bl[:] = 0.0
        for nm, val in (("mesh2d_waterdepth", depth), ("mesh2d_ucx", u), ("mesh2d_ucy", v)):
            var = ds.createVariable(nm, "f8", ("time", "nFaces"))
            var.units = "m" if nm.endswith("depth") else "m s-1"
            var[:] = np.full((len(times), len(faces)), val)
    return path


def run(flow, mesh, contacts, t_end=40.0):
    logs = Logs([3.0], [2.0], [0.0], length=1.0, radius=0.1, density=700.0)
    model = None
    mesh.tag_boundary("outflow", (NX - 0.5, -1, NX + 1, NY + 1))  # the east end is open
    if contacts:
        scen = load_scenario({"contact": {"enabled": True, "walls": True, "restitution": 0.5}})
        model = ContactModel.from_sections(scen["contact"], scen["obstacles"], mesh=mesh)
    Tracker(flow, logs, PhysicsOptions(), contact=model, t_end=t_end).run()
    hits = model.drain_hits() if model else None
    return logs, hits


def test_seam_read_as_is_is_a_wall():
    """The bug: without merging, the seam's 12 edges are boundary edges, and with contacts on
    a log drifting through them is stopped there; with contacts off it crosses."""
    from driftlog.analytic import UniformFlow, on_mesh

    x, y, faces = seamed_grid()
    raw = Mesh(x, y, faces)
    seam = np.isclose(raw.edge_x[raw.boundary_edges], SEAM)
    assert seam.sum() == 2 * NY  # both sides of the seam
    flow = on_mesh(UniformFlow(1.0, 0.3, depth=1.0), raw, times=(0.0, 100.0))
    logs, hits = run(flow, raw, contacts=True, t_end=10.0)  # reaches x = 10 at t = 6.5 s
    assert logs.state[0, 0] < SEAM + 0.1 and len(hits["time"]) >= 5  # held at the seam
    assert np.all(np.abs(hits["x"] - SEAM) < 1e-3)
    logs, _ = run(flow, raw, contacts=False, t_end=10.0)
    assert logs.state[0, 0] > SEAM + 2


@pytest.mark.parametrize("jitter", [0.0, 1e-9])
def test_ugrid_seam_merged_and_crossed(tmp_path, jitter):
    x, y, faces = seamed_grid(jitter=jitter)
    path = write_ugrid(tmp_path / "map.nc", x, y, faces)
    mesh = read_ugrid_mesh(path)
    assert mesh.n_nodes == (NX + 1) * (NY + 1) and mesh.merged_nodes[0] == NY + 1
    assert mesh.boundary_edges.size == 2 * (NX + NY)  # the perimeter only
    assert "7 coincident nodes merged (closer than 1e-06 x the local edge length)" in repr(mesh)
    flow = open_flow_source("auto", path)
    assert flow.mesh.merged_nodes[0] == NY + 1
    on, hits = run(flow, flow.mesh, contacts=True)
    off, _ = run(flow, flow.mesh, contacts=False)
    # a log crossing x = 10 meets nothing there: only the north wall (y = 6) is ever hit
    assert on.status[0] == LEFT and off.status[0] == LEFT  # out through the east end
    assert len(hits["time"]) >= 1 and np.all(np.abs(hits["y"] - NY) < 1e-3)


def test_import_and_info_report_merged_nodes(tmp_path, capsys):
    """`driftlog import` notes the merge; `driftlog info` on the flow file shows it again."""
    from driftlog.cli import main

    x, y, faces = seamed_grid()
    path = write_ugrid(tmp_path / "map.nc", x, y, faces)
    out = tmp_path / "flow.nc"
    assert main(["import", str(path), "-o", str(out)]) == 0
    note = "7 coincident nodes merged (closer than 1e-06 x the local edge length"
    assert note in capsys.readouterr().out
    assert main(["info", str(out)]) == 0
    text = capsys.readouterr().out
    assert f"{(NX + 1) * (NY + 1)} nodes" in text and note in text
    assert main(["info", str(path)]) == 0  # the map file itself
    text = capsys.readouterr().out
    assert "7 coincident nodes merged" in text and "<Mesh 120 faces" in text


def test_real_boundary_kept():
    """A slit of 1 mm between the parts (1e-3 of the 1 m edges: far above the tolerance)
    stays two boundaries; and the outer boundary is untouched by merging."""
    x, y, faces = seamed_grid(gap=1e-3)
    keep, fn, n = merge_coincident_nodes(x, y, faces)
    assert n == 0 and keep.size == x.size
    mesh = Mesh(x[keep], y[keep], fn)
    assert mesh.boundary_edges.size == 2 * (NX + NY) + 2 * NY


def test_tolerance_is_relative_to_the_local_edge_length():
    """Scaled by 1e-4 (a mesh in km read as m) or 1e4, the same seam merges the same way, and
    two nodes 2e-6 edge lengths apart are not merged."""
    x, y, faces = seamed_grid(jitter=0.4e-6)
    for scale in (1e-4, 1.0, 1e4):
        assert merge_coincident_nodes(x * scale, y * scale, faces)[2] == NY + 1
    x, y, faces = seamed_grid(gap=2 * SEAM_TOLERANCE)
    assert merge_coincident_nodes(x, y, faces)[2] == 0
