"""Set-ups of real floods on a mesh: sea boundaries found from the bed, water bodies by region.

A field mesh (a valley running into the sea) comes with no boundary tags: the sea boundary is
found from the geometry (boundary edges whose nodes all lie at or below the sea level), and the
sea itself is every face below the sea level connected to that boundary (a low field inland
stays dry).  ``malpasset_solver`` builds the Malpasset dam break this way from the data's
README (shared/data/malpasset): reservoir at 100 m in its polygon, sea at ``sea_level``, Manning
n = 0.033, reflective walls except the sea.

    from driftlog.floodsetup import malpasset_solver, read_observations
    solver = malpasset_solver("cases/malpasset/data/malpasset_mesh.nc")
    solver.run(4000.0, output="/tmp/malpasset.nc", output_interval=30.0)
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from driftlog.errors import ScenarioError

__all__ = ["low_boundary_edges", "tag_sea", "sea_faces", "check_sea",
           "apply_sea", "fill_sea", "SEA_KEYS",
           "malpasset_depth", "malpasset_solver", "read_observations",
           "MALPASSET_RESERVOIR", "MALPASSET_DAM", "MALPASSET_LEVEL", "MALPASSET_MANNING"]

# the data README's set-up (after George 2011 and TELEMAC's example), mesh coordinates (m)
MALPASSET_DAM = ((4701.18, 4143.41), (4655.5, 4392.10))
MALPASSET_RESERVOIR = ((4701.18, 4143.41), (4655.5, 4392.10), (3000.0, 7000.0), (0.0, 7000.0),
                       (0.0, 1000.0), (5000.0, 1000.0))
MALPASSET_LEVEL = 100.0     # m: reservoir surface at the failure
MALPASSET_MANNING = 0.033   # s m^-1/3 (Strickler 30)


def low_boundary_edges(mesh, level):
    """Boundary edges whose end nodes both lie at or below ``level`` (node bed, m)."""
    if mesh.node_z is None:
        raise ScenarioError("mesh.node_z", None, "a sea boundary is found from the bed: the "
                            "mesh needs node elevations")
    b = mesh.boundary_edges
    top = mesh.node_z[mesh.edge_nodes[b]].max(axis=1)
    return b[top <= level]


def tag_sea(mesh, level=0.0, name="sea"):
    """Tag the boundary edges at or below the sea ``level`` as ``name``; returns them."""
    edges = low_boundary_edges(mesh, level)
    if edges.size == 0:
        raise ScenarioError("sea_level", level, f"no boundary edge of the mesh lies at or below "
                            f"it (lowest boundary node {mesh.node_z.min():.2f} m)")
    mesh.tag_edges(name, edges)
    return edges


def sea_faces(mesh, bed, level, sea_edges):
    """Faces with bed below ``level`` connected (through such faces) to the ``sea_edges``."""
    low = bed < level
    nb = mesh.face_neighbours
    f = np.repeat(np.arange(mesh.n_faces), nb.shape[1])
    g = nb.ravel()
    keep = (g >= 0) & low[f] & low[np.where(g >= 0, g, 0)]
    n = mesh.n_faces
    graph = sp.csr_matrix((np.ones(keep.sum()), (f[keep], g[keep])), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    seeds = mesh.edge_faces[sea_edges, 0]
    seeds = seeds[low[seeds]]
    return low & np.isin(label, np.unique(label[seeds]))


SEA_KEYS = ("level", "boundary", "tag")


def check_sea(spec, key="solver.sea"):
    """Check a ``[solver.sea]`` table: ``level`` (m), ``boundary`` ('level' | 'free'), ``tag``."""
    for k in spec:
        if k not in SEA_KEYS:
            raise ScenarioError(f"{key}.{k}", spec[k], "unknown key; [solver.sea] has "
                                + ", ".join(SEA_KEYS))
    level = spec.get("level")
    if isinstance(level, bool) or not isinstance(level, (int, float)):
        raise ScenarioError(f"{key}.level", level, "the sea surface level (m) is required")
    if spec.get("boundary", "level") not in ("level", "free"):
        raise ScenarioError(f"{key}.boundary", spec["boundary"], "must be 'level' (imposed sea "
                            "level) or 'free' (zero-gradient outflow)")
    if not isinstance(spec.get("tag", "sea"), str) or not spec.get("tag", "sea"):
        raise ScenarioError(f"{key}.tag", spec.get("tag"), "must be a non-empty tag name")


def apply_sea(mesh, spec, boundaries):
    """Tag the coast of a ``[solver.sea]`` table (``check_sea``); returns its edges.

    The boundary edges at or below ``level`` get ``tag`` (``tag_sea``), and ``boundaries`` (a
    dict tag -> condition) the sea's condition unless it names the tag already.
    """
    level = float(spec["level"])
    tag = spec.get("tag", "sea")
    edges = tag_sea(mesh, level, tag) if tag not in mesh.tag_names else mesh.edges_with_tag(tag)
    if spec.get("boundary", "level") == "level":
        boundaries.setdefault(tag, {"type": "level", "value": level})
    else:
        boundaries.setdefault(tag, {"type": "free"})
    return edges


def fill_sea(mesh, bed, h, level, edges):
    """Depths ``h`` with the sea (``sea_faces``) filled to ``level``."""
    sea = sea_faces(mesh, bed, level, edges)
    return np.where(sea, np.maximum(h, level - bed), h)


def malpasset_depth(mesh, bed, sea_edges, sea_level=0.0):
    """Initial depth: reservoir at 100 m in its polygon, sea at ``sea_level``, dry elsewhere."""
    h = np.zeros(mesh.n_faces)
    res = mesh.faces_in_polygon(MALPASSET_RESERVOIR)
    h[res] = np.maximum(MALPASSET_LEVEL - bed[res], 0.0)
    sea = sea_faces(mesh, bed, sea_level, sea_edges) & ~res
    h[sea] = sea_level - bed[sea]
    return h


def malpasset_solver(mesh, order=1, sea_level=0.0, sea="level", **options):
    """The Malpasset dam break, ready to run.

    Parameters
    ----------
    mesh : driftlog.mesh.Mesh or path
        The 46,691-triangle mesh (node bed), or its file; a Mesh gets the ``sea`` tag.
    order : {1, 2}
    sea_level : float
        Sea surface (m): 0 (TELEMAC's example) or -0.5 (GeoClaw).
    sea : {"level", "free"}
        The sea boundary: imposed level ``sea_level`` or zero-gradient outflow.
    **options
        Passed to ``ShallowWaterSolver`` (riemann, cfl, dry_depth, arrival_depth...).
    """
    from driftlog.mesh import Mesh, read_mesh
    from driftlog.solver import ShallowWaterSolver

    spec = {"level": float(sea_level), "boundary": sea}
    check_sea(spec, "sea")
    if not isinstance(mesh, Mesh):
        mesh = read_mesh(mesh)
    boundaries = {}
    coast = apply_sea(mesh, spec, boundaries)
    options.setdefault("manning", MALPASSET_MANNING)
    solver = ShallowWaterSolver(mesh, order=order, boundaries=boundaries, **options)
    solver.set_state(malpasset_depth(mesh, solver.bed, coast, sea_level))
    return solver


def read_observations(path):
    """The observations CSV as a list of dicts.

    Keys id, kind, x, y, max_level_m, arrival_s (NaN where not observed).
    """
    path = Path(path)
    rows = []
    with open(path) as f:
        lines = [ln for ln in f if not ln.startswith("#")]
    for r in csv.DictReader(lines):
        rows.append({"id": r["id"], "kind": r["kind"], "x": float(r["x"]), "y": float(r["y"]),
                     "max_level_m": float(r["max_level_m"]) if r["max_level_m"] else np.nan,
                     "arrival_s": float(r["arrival_s"]) if r["arrival_s"] else np.nan})
    if not rows:
        raise ScenarioError("observations", str(path), "a CSV with id, kind, x, y, "
                            "max_level_m, arrival_s rows")
    return rows
