"""A sea found from the bed: its coast tagged on the mesh, its water filled below a level.

A field mesh (a valley running into the sea) comes with no boundary tags: the sea boundary is
found from the geometry (boundary edges whose nodes all lie at or below the sea level), and the
sea itself is every face below the sea level connected to that boundary (a low field inland
stays dry).  The ``[solver.sea]`` table (``driftlog.solver.config``) uses these helpers; the
Malpasset set-up (``driftlog.floodsetup``) too.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from driftlog.errors import ScenarioError

__all__ = ["low_boundary_edges", "tag_sea", "sea_faces", "check_sea", "apply_sea", "fill_sea",
           "SEA_KEYS"]


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
