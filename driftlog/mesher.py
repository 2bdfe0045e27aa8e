"""Meshes for the scenes: polygons with holes (bridge piers, obstacles) and channels.

Built on Shewchuk's Triangle (``triangle`` on PyPI): quality triangles (minimum angle 30
degrees) no larger than a target size.  Boundary segments carry tags (``wall``, ``inflow``,
``outflow``...) that the solver's boundary conditions and the contact walls use.
"""

from __future__ import annotations

import numpy as np
import triangle

from driftlog.errors import MeshError
from driftlog.mesh import Mesh

__all__ = ["polygon_mesh", "channel_mesh", "circle", "rectangle", "find_crossing",
           "find_misplaced_hole"]


def circle(center, radius, cell_size=None, n=None):
    """Polygon (n, 2) approximating a circle, counter-clockwise; n from the cell size."""
    if n is None:
        n = 24 if cell_size is None else int(np.clip(np.ceil(2 * np.pi * radius / cell_size),
                                                     8, 720))
    a = 2 * np.pi * np.arange(n) / n
    return np.column_stack([center[0] + radius * np.cos(a), center[1] + radius * np.sin(a)])


def rectangle(xmin, ymin, xmax, ymax):
    """Counter-clockwise rectangle polygon."""
    return np.array([[xmin, ymin], [xmax, ymin], [xmax, ymax], [xmin, ymax]], dtype=float)


def _densify(poly, size, closed=True):
    """Split polygon sides longer than ``size`` (so boundary edges match the cell size)."""
    pts = []
    n = len(poly)
    for i in range(n if closed else n - 1):
        a, b = poly[i], poly[(i + 1) % n]
        k = max(int(np.ceil(np.hypot(*(b - a)) / size)), 1)
        pts.append(a + (b - a) * (np.arange(k)[:, None] / k))
    return np.concatenate(pts)


_BLOCK = 512  # sides tested at a time against all the others: bounded memory


def _sides_meet(a0, a1, b0, b1):
    """(n, m) whether side k of a (a0[k] to a1[k]) and side l of b cross or touch."""
    def orient(p, q, r):
        return ((q[..., 0] - p[..., 0]) * (r[..., 1] - p[..., 1])
                - (q[..., 1] - p[..., 1]) * (r[..., 0] - p[..., 0]))

    P0, P1, Q0, Q1 = a0[:, None], a1[:, None], b0[None], b1[None]
    box = ((np.maximum(P0, P1) >= np.minimum(Q0, Q1))
           & (np.maximum(Q0, Q1) >= np.minimum(P0, P1))).all(axis=-1)
    return (box & (orient(P0, P1, Q0) * orient(P0, P1, Q1) <= 0)
            & (orient(Q0, Q1, P0) * orient(Q0, Q1, P1) <= 0))


def find_crossing(rings):
    """The first two sides of closed polygons ``rings`` that cross or touch, or None.

    Returns (a, i, b, j): side i of ring a (from its point i to point i + 1) meets side j of
    ring b (a <= b; consecutive sides of a ring, which share a point, are not counted).  Triangle
    fails on such outlines, or crashes the process (a segmentation fault).  O(n^2) in the sides
    of a ring, over pairs of rings whose boxes overlap.
    """
    rings = [np.asarray(r, dtype=float) for r in rings]
    ends = [(r, np.roll(r, -1, axis=0)) for r in rings]
    boxes = [(r.min(axis=0), r.max(axis=0)) for r in rings]
    for a, (a0, a1) in enumerate(ends):
        for b in range(a, len(rings)):
            if np.any(boxes[a][1] < boxes[b][0]) or np.any(boxes[b][1] < boxes[a][0]):
                continue
            b0, b1 = ends[b]
            n, m = len(a0), len(b0)
            for k0 in range(0, n, _BLOCK):
                meet = _sides_meet(a0[k0:k0 + _BLOCK], a1[k0:k0 + _BLOCK], b0, b1)
                if a == b:  # a side and itself or its neighbours share points
                    i = np.arange(k0, min(k0 + _BLOCK, n))[:, None]
                    gap = np.abs(i - np.arange(m)[None])
                    meet &= (gap > 1) & (gap < n - 1)
                hit = np.argwhere(meet)
                if hit.size:
                    return a, int(hit[0, 0]) + k0, b, int(hit[0, 1])
    return None


def find_misplaced_hole(outer, holes):
    """The first hole outside ``outer`` or inside another hole, or None.

    Returns (k, None) for hole k outside the outline, (k, j) for hole k inside hole j.  The
    rings must not cross (``find_crossing``): one point of a hole then tells where it lies.
    """
    from matplotlib.path import Path as MplPath

    holes = [np.asarray(h, dtype=float) for h in holes]
    ring = MplPath(np.asarray(outer, dtype=float))
    for k, h in enumerate(holes):
        if not ring.contains_point(h[0]):
            return k, None
        for j, other in enumerate(holes):
            if j != k and MplPath(other).contains_point(h[0]):
                return k, j
    return None


def polygon_mesh(outer, cell_size, holes=(), side_tags=None, min_angle=30.0, refine=None) -> Mesh:
    """Triangulate a polygon with holes.

    Parameters
    ----------
    outer : (n, 2) array
        Outer boundary, counter-clockwise or not.
    cell_size : float
        Target edge length (m): triangles have area <= sqrt(3)/4 cell_size^2.
    holes : list of (m, 2) arrays
        Holes (piers, islands); their edges are tagged ``wall``.
    side_tags : dict {side index: tag}
        Tags for sides of the outer polygon (side i runs from vertex i to i + 1); others ``wall``.
    refine : callable(x, y) -> cell size, optional
        Variable target size (evaluated at triangle centroids, one refinement pass).
    """
    outer = np.asarray(outer, dtype=float)
    if outer.ndim != 2 or outer.shape[0] < 3 or outer.shape[1] != 2:
        raise MeshError(f"outer polygon must be (n >= 3, 2), got shape {outer.shape}")
    if not (cell_size > 0 and np.isfinite(cell_size)):
        raise MeshError(f"cell_size must be a finite number > 0, got {cell_size}")
    if not np.all(np.isfinite(outer)):
        raise MeshError("outer polygon holds NaN or inf coordinates")
    # refuse before Triangle runs out of memory (it fails after minutes with "Triangulation
    # failed"): 1.55 x area / equilateral-triangle area, ~1.5 kB a triangle while meshing
    x, y = outer[:, 0], outer[:, 1]
    est = 1.55 * 0.5 * abs(np.dot(x, np.roll(y, 1)) - np.dot(y, np.roll(x, 1))) / (
        np.sqrt(3) / 4 * cell_size ** 2)
    from driftlog.resources import check_fits

    check_fits(est * 1500.0, f"meshing with cell_size = {cell_size:g} m (about {est:.3g} "
               "triangles)", "use a larger cell_size")
    holes = [np.asarray(h, dtype=float) for h in holes]
    crossing = find_crossing([outer] + holes)
    if crossing is not None:
        a, i, b, j = crossing
        name = ["the outline"] + [f"hole {k}" for k in range(len(holes))]
        raise MeshError(f"side {i} of {name[a]} crosses or touches side {j} of {name[b]} (side "
                        "i runs from point i to point i + 1): the mesher needs simple polygons, "
                        "the holes inside the outline without touching it or each other")
    misplaced = find_misplaced_hole(outer, holes)
    if misplaced is not None:
        k, j = misplaced
        raise MeshError(f"hole {k} lies " + ("outside the outline" if j is None else
                                             f"inside hole {j}") + ": holes must lie inside "
                        "the outline, apart from each other")
    tags = ["wall"]
    side_tags = side_tags or {}
    verts, segs, marks = [], [], []
    start = 0
    n = len(outer)
    for i in range(n):
        a, b = outer[i], outer[(i + 1) % n]
        k = max(int(np.ceil(np.hypot(*(b - a)) / cell_size)), 1)
        pts = a + (b - a) * (np.arange(k)[:, None] / k)
        tag = side_tags.get(i, "wall")
        if tag not in tags:
            tags.append(tag)
        verts.append(pts)
        idx = start + np.arange(k)
        segs.append(np.column_stack([idx, idx + 1]))
        marks.append(np.full(k, tags.index(tag) + 1))
        start += k
    segs[-1][-1, 1] = 0  # close the ring
    hole_points = []
    for h in holes:
        h = np.asarray(h, dtype=float)
        hp = _densify(h, cell_size)
        m = len(hp)
        idx = start + np.arange(m)
        verts.append(hp)
        segs.append(np.column_stack([idx, np.roll(idx, -1)]))
        marks.append(np.full(m, 1))
        start += m
        hole_points.append(_interior_point(h))
    data = dict(vertices=np.concatenate(verts), segments=np.concatenate(segs),
                segment_markers=np.concatenate(marks).astype(np.int32))
    if hole_points:
        data["holes"] = np.array(hole_points)
    area = np.sqrt(3) / 4 * cell_size ** 2
    # positional notation: Triangle reads "a6.8e-05" as area 6.8 followed by its -e switch
    a = np.format_float_positional(area, precision=10, unique=False, fractional=False,
                                   trim="-")
    try:
        out = triangle.triangulate(data, f"pq{min_angle:g}a{a}")
    except RuntimeError as exc:  # Triangle: self-intersecting outline, holes outside...
        raise MeshError(f"the mesher cannot triangulate this outline with cell_size = "
                        f"{cell_size:g} m ({exc}); check that the outline does not cross "
                        "itself and the holes (piers) lie inside it without overlapping") from None
    if refine is not None:
        tri = out["triangles"]
        c = out["vertices"][tri].mean(axis=1)
        size = np.asarray(refine(c[:, 0], c[:, 1]), dtype=float)
        out["triangle_max_area"] = np.sqrt(3) / 4 * np.minimum(size, cell_size) ** 2
        out = triangle.triangulate(out, f"pq{min_angle:g}ra")
    mesh = Mesh(out["vertices"][:, 0], out["vertices"][:, 1], out["triangles"])
    _tag_from_segments(mesh, out["segments"], out["segment_markers"].ravel(), tags)
    return mesh


def _interior_point(poly):
    """A point strictly inside a simple polygon (centroid if inside, else a nudged ear point)."""
    from matplotlib.path import Path as MplPath

    path = MplPath(poly)
    c = poly.mean(axis=0)
    if path.contains_point(c):
        return c
    for i in range(len(poly)):
        p = (poly[i - 1] + poly[i] + poly[(i + 1) % len(poly)]) / 3
        if path.contains_point(p):
            return p
    raise MeshError("cannot find a point inside a hole polygon (self-intersecting?)")


def _tag_from_segments(mesh, segs, marks, tags):
    e = mesh.edge_nodes
    b = mesh.boundary_edges
    key_b = np.minimum(e[b, 0], e[b, 1]) * mesh.n_nodes + np.maximum(e[b, 0], e[b, 1])
    key_s = np.minimum(segs[:, 0], segs[:, 1]) * mesh.n_nodes + np.maximum(segs[:, 0], segs[:, 1])
    order = np.argsort(key_s)
    pos = np.searchsorted(key_s[order], key_b)
    pos = np.minimum(pos, key_s.size - 1)
    found = key_s[order][pos] == key_b
    mark = np.where(found, marks[order][pos], 1)
    mesh.tag_names = list(tags)
    mesh.edge_tag[b] = (mark - 1).astype(np.int16)


def channel_mesh(length, width, cell_size, x0=0.0, y0=0.0, holes=(), structured=False) -> Mesh:
    """A rectangular channel [x0, x0 + length] x [y0, y0 + width].

    The left side (x = x0) is tagged ``inflow``, the right side ``outflow``, the banks and any
    holes ``wall``.  ``structured`` gives a grid of squares (no holes allowed).
    """
    for name, v in (("length", length), ("width", width), ("cell_size", cell_size)):
        if not (np.isfinite(v) and v > 0):
            raise MeshError(f"channel {name} = {v}: must be a finite number > 0 (m)")
    if structured:
        if holes:
            raise MeshError("a structured channel cannot have holes; use structured = false")
        nx = max(int(round(length / cell_size)), 1)
        ny = max(int(round(width / cell_size)), 1)
        mesh = Mesh.regular_grid(nx, ny, length / nx, width / ny, x0, y0)
        eps = 1e-9 * length
        mesh.tag_boundary("inflow", lambda x, y: x < x0 + eps)
        mesh.tag_boundary("outflow", lambda x, y: x > x0 + length - eps)
        return mesh
    outer = rectangle(x0, y0, x0 + length, y0 + width)
    return polygon_mesh(outer, cell_size, holes=holes, side_tags={1: "outflow", 3: "inflow"})
