"""Seams: coincident nodes of partitioned meshes (D-Flow FM, ANUGA, HEC-RAS) found and merged.

An internal line with duplicated nodes would be a wall to the contact model; merging the
nodes (docs/design.md, readers) makes it an ordinary internal line again.
"""

from __future__ import annotations

import numpy as np

__all__ = ["FILL", "SEAM_TOLERANCE", "merge_coincident_nodes"]

FILL = -1  # padding of face-node tables (faces with fewer nodes than the widest)

#: nodes closer than this fraction of their shortest edge are one node (``merge_coincident``)
SEAM_TOLERANCE = 1e-6


def merge_coincident_nodes(node_x, node_y, face_nodes, fill_value=FILL, start_index=0,
                           rel_tol=SEAM_TOLERANCE):
    """Merge nodes that coincide: the seams of partitioned meshes (D-Flow FM, ANUGA, HEC-RAS).

    Two nodes are one when their distance is at most ``rel_tol`` times the shortest edge
    touching either of them (a tolerance relative to the local edge length, so a fine mesh in
    millimetres and a coarse one in kilometres are treated alike; two real nodes are never
    that close on a valid mesh).  Faces keep their node order; each merged group keeps the
    coordinates of its lowest-numbered node.

    Returns
    -------
    keep : int array
        The original index of each node of the merged mesh.
    face_nodes : int array
        The faces on the merged nodes (0-based, padding ``FILL``).
    n_merged : int
        Nodes removed (0 when there was no seam).
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    x = np.asarray(node_x, np.float64)
    y = np.asarray(node_y, np.float64)
    fn = np.asarray(face_nodes, np.int64)
    pad = (fn == fill_value) | (fn < start_index)
    fn = np.where(pad, FILL, fn - start_index)
    n = x.size
    if n < 2 or fn.size == 0 or fn.max() >= n:
        return np.arange(n), fn, 0
    # candidates: pairs within rel_tol of the domain's diagonal (no edge is longer), then each
    # pair against its own nodes' shortest edges, computed for the candidates only (a mesh
    # without seams costs one tree query)
    diag = float(np.hypot(np.ptp(x), np.ptp(y)))
    tree = cKDTree(np.column_stack([x, y]))
    pairs = tree.query_pairs(rel_tol * diag, output_type="ndarray")
    if pairs.size:
        cand = np.unique(pairs)
        nxt = np.roll(fn, -1, axis=1)
        nxt = np.where(nxt < 0, fn[:, :1], nxt)  # the last real node closes on the first
        valid = fn >= 0
        a, b = fn[valid], nxt[valid]
        touch = np.isin(a, cand) | np.isin(b, cand)
        a, b = a[touch], b[touch]
        length = np.hypot(x[a] - x[b], y[a] - y[b])
        local = np.full(n, np.inf)
        np.minimum.at(local, a, length)
        np.minimum.at(local, b, length)
        d = np.hypot(x[pairs[:, 0]] - x[pairs[:, 1]], y[pairs[:, 0]] - y[pairs[:, 1]])
        lim = rel_tol * np.minimum(local[pairs[:, 0]], local[pairs[:, 1]])
        pairs = pairs[d <= lim]
    if pairs.size == 0:
        return np.arange(n), fn, 0
    g = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, label = connected_components(g, directed=False)
    # representative: the lowest node of each group, numbered in the order of the nodes
    rep = np.full(label.max() + 1, n, np.int64)
    np.minimum.at(rep, label, np.arange(n))
    keep = np.sort(rep)
    new_of_old = np.searchsorted(keep, rep[label])
    out = np.where(fn >= 0, new_of_old[np.maximum(fn, 0)], FILL)
    return keep, out, int(n - keep.size)
