"""Set up an ANUGA domain on a driftlog triangle mesh, so that both solve the same scene.

ANUGA (``pip install anuga``, a benchmark-only dependency) takes the mesh as
``anuga.Domain(points, triangles, boundary)``; triangle i of the domain is face i of the
driftlog mesh (same nodes, same order), and each boundary side carries the driftlog tag of
its edge.  ANUGA names a side by ``(triangle, k)``, k the vertex opposite to it.  Its results
(``.sww``) are read back by ``driftlog.adapters.anuga.open_anuga``.
"""

from __future__ import annotations

import numpy as np

from driftlog.errors import FlowFileError
from driftlog.mesh import Mesh

__all__ = ["anuga_available", "anuga_boundary", "anuga_domain"]


def anuga_available() -> bool:
    """Whether ANUGA can be imported here."""
    try:
        import anuga  # noqa: F401
    except ImportError:
        return False
    return True


def anuga_boundary(mesh: Mesh) -> dict:
    """ANUGA's boundary dictionary ``{(triangle, opposite vertex): tag}`` of the mesh."""
    if mesh.max_face_nodes != 3:
        raise FlowFileError(f"ANUGA takes triangles only; the mesh has faces of up to "
                            f"{mesh.max_face_nodes} nodes")
    b = mesh.boundary_edges
    f = mesh.edge_faces[b, 0]
    # face f is counter-clockwise and its boundary edge runs from node k to node k + 1
    k = np.argmax(mesh.face_nodes[f] == mesh.edge_nodes[b, 0][:, None], axis=1)
    tags = [mesh.tag_names[t] for t in mesh.edge_tag[b]]
    return {(int(fi), int((ki + 2) % 3)): tag for fi, ki, tag in zip(f, k, tags, strict=True)}


def anuga_domain(mesh: Mesh, bed=None, depth=None, flow_algorithm="DE0", boundaries=None,
                 manning=0.0, name="driftlog", datadir=".", threads=None):
    """An ``anuga.Domain`` on the mesh's triangles, with bed, depth and boundaries set.

    Parameters
    ----------
    mesh : Mesh
        Triangles only; boundary tags become ANUGA's boundary tags.
    bed : array (n_faces,) or float, optional
        Bed elevation at the centroids (m); default ``mesh.face_bed()`` or 0.
    depth : array (n_faces,) or float, optional
        Initial water depth at the centroids (m); default 0 (dry).
    flow_algorithm : str
        ANUGA's flow algorithm ('DE0', its default; 'DE1', 'DE2'...).
    boundaries : dict tag -> callable(domain) -> ANUGA boundary, optional
        Tags not given are reflective walls.
    manning : float or array
        Manning's n (ANUGA's 'friction' quantity).
    name, datadir : str
        Name of the ``.sww`` ANUGA writes, and its folder.
    threads : int, optional
        ANUGA's OpenMP threads.
    """
    import anuga

    boundary = anuga_boundary(mesh)
    nf = mesh.n_faces
    if bed is None:
        bed = mesh.face_bed()
        bed = 0.0 if bed is None else bed
    bed = np.broadcast_to(np.asarray(bed, float), (nf,))
    depth = np.broadcast_to(np.asarray(0.0 if depth is None else depth, float), (nf,))
    if not np.all(depth >= 0):
        raise FlowFileError(f"initial depth must be >= 0 m; min {depth.min()}")
    dom = anuga.Domain(np.column_stack([mesh.node_x, mesh.node_y]), mesh.face_nodes, boundary)
    dom.set_flow_algorithm(flow_algorithm)
    if threads is not None:
        dom.set_omp_num_threads(int(threads))
    dom.set_name(name)
    dom.set_datadir(str(datadir))
    dom.set_quantity("elevation", bed, location="centroids")
    dom.set_quantity("friction", np.broadcast_to(np.asarray(manning, float), (nf,)),
                     location="centroids")
    dom.set_quantity("stage", bed + depth, location="centroids")
    given = dict(boundaries or {})
    unknown = set(given) - set(boundary.values())
    if unknown:
        raise FlowFileError(f"boundaries {sorted(unknown)} name no boundary tag of the mesh "
                            f"(tags: {sorted(set(boundary.values()))})")
    wall = anuga.Reflective_boundary(dom)
    dom.set_boundary({tag: (given[tag](dom) if tag in given else wall)
                      for tag in set(boundary.values())})
    return dom
