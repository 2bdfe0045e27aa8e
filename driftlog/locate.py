"""Point location on unstructured meshes: a uniform bin grid for the first look-up, then a walk.

A query point with a hint (the face it was in before) walks across faces towards the point,
so a log that moved a little costs O(1).  Without a hint, or when the walk leaves the mesh
(non-convex domains, holes), the uniform bin grid gives the candidate faces.

Faces are convex polygons given counter-clockwise (``Mesh`` checks and repairs this).
A point on an edge or a vertex belongs to every face that touches it; either is returned.

What the locator reads (the mesh's faces, neighbours and nodes, and the bin grid) travels as
one ``Locator`` (a named tuple numba passes by value, packed once per mesh by
``Mesh.locator()``): kernels that locate points take it as one argument.
"""

from typing import NamedTuple

import numba as nb
import numpy as np

from driftlog._numba import kernel

__all__ = ["BinGrid", "Locator", "build_bin_grid", "locate_one", "locate_points",
           "point_in_face", "brute_force_locate"]

OUTSIDE = -1
MAX_WALK = 64


class Locator(NamedTuple):
    """The mesh and bin-grid arrays of point location, as one kernel argument.

    ``face_nodes`` (n_faces, max nodes) counter-clockwise, ``face_n`` nodes per face,
    ``face_nbr`` (n_faces, max nodes) the face across each edge (-1: boundary), ``node_x``,
    ``node_y``; the bin grid: origin ``x0``, ``y0``, inverse bin sizes, ``nbx`` x ``nby`` bins,
    the faces of bin b in ``bin_faces[bin_start[b]:bin_start[b + 1]]``.
    """

    face_nodes: np.ndarray
    face_n: np.ndarray
    face_nbr: np.ndarray
    node_x: np.ndarray
    node_y: np.ndarray
    x0: float
    y0: float
    inv_dx: float
    inv_dy: float
    nbx: int
    nby: int
    bin_start: np.ndarray
    bin_faces: np.ndarray


@nb.njit(cache=True, inline="always")
def _edge_side(px, py, ax, ay, bx, by):
    """Cross product (b - a) x (p - a) and the squared scale that bounds its round-off."""
    ex, ey = bx - ax, by - ay
    dx, dy = px - ax, py - ay
    return ex * dy - ey * dx, ex * ex + ey * ey + dx * dx + dy * dy


@nb.njit(cache=True)
def point_in_face(px, py, f, face_nodes, face_n, node_x, node_y):
    """True where point (px, py) lies in face f (closed: edges and vertices included)."""
    n = face_n[f]
    for k in range(n):
        a = face_nodes[f, k]
        b = face_nodes[f, k + 1] if k + 1 < n else face_nodes[f, 0]  # no integer modulo
        c, s = _edge_side(px, py, node_x[a], node_y[a], node_x[b], node_y[b])
        if not c >= -1e-12 * s:  # also rejects NaN
            return False
    return True


@nb.njit(cache=True)
def _walk(px, py, f, loc):
    """Walk from face f towards the point; the face that holds it, or -1 if the walk gives up."""
    face_nodes, face_n, face_nbr = loc.face_nodes, loc.face_n, loc.face_nbr
    node_x, node_y = loc.node_x, loc.node_y
    for _ in range(MAX_WALK):
        n = face_n[f]
        worst = 0.0
        kworst = -1
        for k in range(n):
            a = face_nodes[f, k]
            b = face_nodes[f, k + 1] if k + 1 < n else face_nodes[f, 0]  # no integer modulo
            c, s = _edge_side(px, py, node_x[a], node_y[a], node_x[b], node_y[b])
            if c < -1e-12 * s:
                # normalised distance outside this edge; leave by the edge the point is
                # farthest beyond
                d = c / np.sqrt(s)
                if d < worst:
                    worst = d
                    kworst = k
        if kworst < 0:
            return f
        g = face_nbr[f, kworst]
        if g < 0:
            return OUTSIDE
        f = g
    return OUTSIDE


@nb.njit(cache=True)
def _bin_search(px, py, loc):
    nbx, nby = loc.nbx, loc.nby
    fx = (px - loc.x0) * loc.inv_dx
    fy = (py - loc.y0) * loc.inv_dy
    if not (fx >= 0.0 and fy >= 0.0 and fx <= nbx and fy <= nby):  # also rejects NaN
        return OUTSIDE
    i = min(int(fx), nbx - 1)
    j = min(int(fy), nby - 1)
    b = j * nbx + i
    for k in range(loc.bin_start[b], loc.bin_start[b + 1]):
        f = loc.bin_faces[k]
        if point_in_face(px, py, f, loc.face_nodes, loc.face_n, loc.node_x, loc.node_y):
            return f
    return OUTSIDE


@nb.njit(cache=True)
def locate_one(px, py, hint, loc):
    """The face holding (px, py), -1 outside; walks from ``hint`` when it is a face index."""
    if not (np.isfinite(px) and np.isfinite(py)):
        return OUTSIDE
    if hint >= 0:
        f = _walk(px, py, hint, loc)
        if f >= 0:
            return f
    return _bin_search(px, py, loc)


@kernel(nrt=False)
def locate_points(px, py, face, loc):
    """Locate every point in place: ``face`` holds the hints on entry and the faces on return."""
    for i in nb.prange(px.shape[0]):
        face[i] = locate_one(px[i], py[i], face[i], loc)


@nb.njit(cache=True)
def _bins_of_faces(fxmin, fymin, fxmax, fymax, x0, y0, inv_dx, inv_dy, nbx, nby, bin_start,
                   bin_faces, fill):
    """Count the faces of each bin (``fill`` False, into ``bin_start[:-1]``), or list them."""
    pos = bin_start[:-1].copy()
    for f in range(fxmin.shape[0]):
        i0 = max(int((fxmin[f] - x0) * inv_dx), 0)
        i1 = min(int((fxmax[f] - x0) * inv_dx), nbx - 1)
        j0 = max(int((fymin[f] - y0) * inv_dy), 0)
        j1 = min(int((fymax[f] - y0) * inv_dy), nby - 1)
        for j in range(j0, j1 + 1):
            for i in range(i0, i1 + 1):
                b = j * nbx + i
                if fill:
                    bin_faces[pos[b]] = f
                    pos[b] += 1
                else:
                    bin_start[b] += 1


class BinGrid:
    """A uniform grid of bins over the mesh's bounding box, each listing the faces it overlaps."""

    def __init__(self, x0, y0, inv_dx, inv_dy, nbx, nby, bin_start, bin_faces):
        self.x0, self.y0 = float(x0), float(y0)
        self.inv_dx, self.inv_dy = float(inv_dx), float(inv_dy)
        self.nbx, self.nby = int(nbx), int(nby)
        self.bin_start, self.bin_faces = bin_start, bin_faces

    def args(self):
        """The grid as the positional arguments of the kernels."""
        return (self.x0, self.y0, self.inv_dx, self.inv_dy, self.nbx, self.nby,
                self.bin_start, self.bin_faces)


def build_bin_grid(face_xmin, face_ymin, face_xmax, face_ymax, faces_per_bin=1.0) -> BinGrid:
    """Bin grid with about ``faces_per_bin`` faces per bin on average, square-ish bins."""
    nf = face_xmin.shape[0]
    xmin, xmax = float(face_xmin.min()), float(face_xmax.max())
    ymin, ymax = float(face_ymin.min()), float(face_ymax.max())
    wx = max(xmax - xmin, 1e-300)
    wy = max(ymax - ymin, 1e-300)
    nbins = max(int(nf / faces_per_bin), 1)
    side = np.sqrt(wx * wy / nbins)
    nbx = int(min(max(round(wx / side), 1), 1 << 15))
    nby = int(min(max(round(wy / side), 1), 1 << 15))
    # pad by a relative epsilon so points on the outer edges fall inside the grid
    pad_x, pad_y = 1e-9 * wx, 1e-9 * wy
    x0, y0 = xmin - pad_x, ymin - pad_y
    inv_dx = nbx / (wx + 2 * pad_x)
    inv_dy = nby / (wy + 2 * pad_y)
    box = (face_xmin, face_ymin, face_xmax, face_ymax, x0, y0, inv_dx, inv_dy, nbx, nby)
    counts = np.zeros(nbx * nby + 1, dtype=np.int64)
    _bins_of_faces(*box, counts, np.empty(0, np.int64), False)
    bin_start = np.zeros(nbx * nby + 1, dtype=np.int64)
    np.cumsum(counts[:-1], out=bin_start[1:])
    bin_faces = np.empty(bin_start[-1], dtype=np.int64)
    _bins_of_faces(*box, bin_start, bin_faces, True)
    return BinGrid(x0, y0, inv_dx, inv_dy, nbx, nby, bin_start, bin_faces)


@nb.njit(cache=True, parallel=True)
def brute_force_locate(px, py, face_nodes, face_n, node_x, node_y):
    """Reference locator for tests: number of faces holding each point and the first one."""
    count = np.zeros(px.shape[0], dtype=np.int64)
    first = np.full(px.shape[0], -1, dtype=np.int64)
    for i in nb.prange(px.shape[0]):
        for f in range(face_n.shape[0]):
            if point_in_face(px[i], py[i], f, face_nodes, face_n, node_x, node_y):
                if count[i] == 0:
                    first[i] = f
                count[i] += 1
    return count, first
