"""Unstructured 2D meshes of convex polygons (UGRID style), their topology and readers.

A ``Mesh`` holds nodes and a face-node table padded with -1 (UGRID ``face_node_connectivity``),
and derives what the solver, the samplers and the contact code need: edges, the faces on each
side of an edge, face neighbours, areas, centroids, inradii, and boundary edges with tags.

Faces are triangles, quadrilaterals or any convex polygon (HEC-RAS cells have up to 8 sides),
mixed, padded with -1 to the widest.  Faces are stored counter-clockwise; clockwise faces are
reversed on construction (a documented repair).  Degenerate faces (zero area, repeated nodes)
and non-convex polygons are errors (the point locator and the sampler's fan of triangles need
convex faces).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import scipy.sparse as sp

from driftlog.errors import MeshError, geographic_error
from driftlog.locate import Locator, build_bin_grid, locate_points
from driftlog.nodal import lsq_node_operators
from driftlog.seams import FILL, SEAM_TOLERANCE, merge_coincident_nodes

__all__ = ["Mesh", "read_mesh", "read_ugrid_mesh", "merge_coincident_nodes", "mesh_merging_seams",
           "SEAM_TOLERANCE", "geographic_attribute", "LENGTH_UNITS", "length_unit_factor"]

DEFAULT_TAG = "wall"


def _as_points(a, name):
    a = np.ascontiguousarray(a, dtype=np.float64)
    if a.ndim != 1:
        raise MeshError(f"{name} must be a 1-D array of coordinates, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        bad = np.flatnonzero(~np.isfinite(a))[:5]
        raise MeshError(f"{name} has non-finite values at nodes {bad.tolist()}")
    return a


class Mesh:
    """A 2D mesh of convex polygons (triangles, quadrilaterals and larger polygons, mixed).

    Parameters
    ----------
    node_x, node_y : array_like, shape (n_nodes,)
        Node coordinates (m).
    face_nodes : array_like of int, shape (n_faces, max_face_nodes)
        Nodes of each face, padded with ``fill_value``.
    fill_value : int, optional
        Padding value in ``face_nodes`` (any negative value is also taken as padding).
    start_index : int, optional
        0 or 1: the index of the first node in ``face_nodes`` (UGRID ``start_index``).
    node_z : array_like, optional
        Bed elevation at the nodes (m).
    repair : bool, optional
        Reverse clockwise faces (default).  If False, a clockwise face is an error.
    """

    def __init__(self, node_x, node_y, face_nodes, fill_value=FILL, start_index=0, node_z=None,
                 repair=True):
        self.node_x = _as_points(node_x, "node_x")
        self.node_y = _as_points(node_y, "node_y")
        if self.node_x.shape != self.node_y.shape:
            raise MeshError(f"node_x and node_y differ in length: {self.node_x.size} and "
                            f"{self.node_y.size}")
        self.node_z = None if node_z is None else _as_points(node_z, "node_z")
        if self.node_z is not None and self.node_z.shape != self.node_x.shape:
            raise MeshError(f"node_z has {self.node_z.size} values for {self.node_x.size} nodes")
        fn = np.array(face_nodes, dtype=np.int64, copy=True)
        if fn.ndim != 2 or fn.shape[1] < 3:
            raise MeshError(f"face_nodes must have shape (n_faces, >= 3), got {fn.shape}")
        if start_index not in (0, 1):
            raise MeshError(f"start_index must be 0 or 1, got {start_index!r}")
        pad = (fn == fill_value) | (fn < start_index)
        fn = fn - start_index
        fn[pad] = FILL
        self.face_nodes, self.face_n = self._compact(fn)
        nmax = int(self.face_n.max(initial=0))
        if self.face_nodes.shape[0] == 0:
            raise MeshError("the mesh has no faces")
        self.face_nodes = np.ascontiguousarray(self.face_nodes[:, :nmax])
        if self.face_nodes.max() >= self.n_nodes:
            bad = np.flatnonzero((self.face_nodes >= self.n_nodes).any(axis=1))[:5]
            raise MeshError(f"faces {bad.tolist()} refer to nodes beyond the {self.n_nodes} "
                            "given (wrong start_index?)")
        self.n_reversed = self._orient(repair)
        self._geometry()
        self._topology()
        self.tag_names = [DEFAULT_TAG]
        self.edge_tag = np.where(self.edge_faces[:, 1] < 0, 0, -1).astype(np.int16)
        self._bins = None
        self._locator = None
        self._node_interp = None

    # ----------------------------------------------------------------- construction
    @staticmethod
    def _compact(fn):
        """Move padding to the end of each row; count the nodes of each face."""
        valid = fn >= 0
        n = valid.sum(axis=1)
        if np.any(n < 3):
            bad = np.flatnonzero(n < 3)[:5]
            raise MeshError(f"faces {bad.tolist()} have fewer than 3 nodes")
        if not np.all(valid[np.arange(fn.shape[1]) < n[:, None]]):
            order = np.argsort(~valid, axis=1, kind="stable")
            fn = np.take_along_axis(fn, order, axis=1)
        return np.ascontiguousarray(fn), n.astype(np.int64)

    def _face_coords(self):
        fn = np.where(self.face_nodes >= 0, self.face_nodes, self.face_nodes[:, :1])
        return self.node_x[fn], self.node_y[fn]

    def _signed_area(self):
        x, y = self._face_coords()
        xn, yn = np.roll(x, -1, axis=1), np.roll(y, -1, axis=1)
        # padded slots repeat node 0, so wrap-around terms for triangles in a quad table cancel
        return 0.5 * np.sum(x * yn - xn * y, axis=1)

    def _orient(self, repair):
        area = self._signed_area()
        x, y = self._face_coords()
        scale = (x.max(axis=1) - x.min(axis=1)) * (y.max(axis=1) - y.min(axis=1))
        degenerate = ~(np.abs(area) > 1e-12 * np.maximum(scale, 1e-300)) | (scale <= 0)
        # a repeated node in a face also makes it degenerate
        fn = self.face_nodes
        for a in range(fn.shape[1]):
            for b in range(a + 1, fn.shape[1]):
                degenerate |= (fn[:, a] == fn[:, b]) & (fn[:, a] >= 0)
        if np.any(degenerate):
            bad = np.flatnonzero(degenerate)
            raise MeshError(f"{bad.size} degenerate faces (zero area or repeated nodes), "
                            f"first {bad[:5].tolist()}")
        cw = area < 0
        if np.any(cw):
            if not repair:
                raise MeshError(f"{cw.sum()} faces are clockwise, first {np.flatnonzero(cw)[:5]}")
            for k in np.unique(self.face_n[cw]):
                rows = cw & (self.face_n == k)
                self.face_nodes[rows, :k] = self.face_nodes[rows, :k][:, ::-1]
        self._check_convex()
        return int(cw.sum())

    def _check_convex(self):
        """Every face with more than 3 nodes turns left at each node (strictly convex)."""
        big = np.flatnonzero(self.face_n > 3)
        if big.size == 0:
            return
        fn = self.face_nodes[big]
        n = self.face_n[big]
        k = np.arange(fn.shape[1])
        valid = k[None, :] < n[:, None]
        # next and next-but-one node of each slot, wrapping within each face's own count
        nxt = np.where(k[None, :] + 1 < n[:, None], k[None, :] + 1, k[None, :] + 1 - n[:, None])
        nx2 = np.where(k[None, :] + 2 < n[:, None], k[None, :] + 2, k[None, :] + 2 - n[:, None])
        a = np.where(valid, fn, fn[:, :1])
        b = np.take_along_axis(fn, np.where(valid, nxt, 0), axis=1)
        c = np.take_along_axis(fn, np.where(valid, nx2, 0), axis=1)
        x, y = self.node_x, self.node_y
        turn = ((x[b] - x[a]) * (y[c] - y[b]) - (y[b] - y[a]) * (x[c] - x[b]))
        bad = big[((turn <= 0) & valid).any(axis=1)]
        if bad.size:
            kinds = "quadrilaterals" if np.all(self.face_n[bad] == 4) else "polygons"
            raise MeshError(f"{bad.size} non-convex {kinds} (first {bad[:5].tolist()}); "
                            "split them into triangles")

    def _geometry(self):
        x, y = self._face_coords()
        xn, yn = np.roll(x, -1, axis=1), np.roll(y, -1, axis=1)
        cross = x * yn - xn * y
        area = 0.5 * cross.sum(axis=1)
        self.face_area = area
        self.face_x = ((x + xn) * cross).sum(axis=1) / (6.0 * area)
        self.face_y = ((y + yn) * cross).sum(axis=1) / (6.0 * area)
        perim = np.hypot(xn - x, yn - y).sum(axis=1)
        # 2 A / P: exact for triangles and for polygons with an incircle
        self.face_inradius = 2.0 * area / perim
        self.face_xmin, self.face_xmax = x.min(axis=1), x.max(axis=1)
        self.face_ymin, self.face_ymax = y.min(axis=1), y.max(axis=1)

    def _topology(self):
        nf, nmax = self.face_nodes.shape
        k = np.arange(nmax)
        valid = k[None, :] < self.face_n[:, None]
        nxt = np.where(k[None, :] + 1 < self.face_n[:, None], k[None, :] + 1, 0)
        a = self.face_nodes
        b = np.take_along_axis(self.face_nodes, np.broadcast_to(nxt, a.shape), axis=1)
        fa, fb = a[valid], b[valid]
        face = np.broadcast_to(np.arange(nf)[:, None], a.shape)[valid]
        local = np.broadcast_to(k[None, :], a.shape)[valid]
        lo, hi = np.minimum(fa, fb), np.maximum(fa, fb)
        key = lo * np.int64(self.n_nodes) + hi
        order = np.argsort(key, kind="stable")
        key_s = key[order]
        first = np.ones(key_s.size, dtype=bool)
        first[1:] = key_s[1:] != key_s[:-1]
        edge_id_sorted = np.cumsum(first) - 1
        n_edges = int(edge_id_sorted[-1]) + 1
        counts = np.bincount(edge_id_sorted, minlength=n_edges)
        if np.any(counts > 2):
            bad = np.flatnonzero(counts > 2)[:5]
            raise MeshError(f"edges shared by more than two faces (non-manifold mesh), "
                            f"e.g. edges {bad.tolist()}")
        edge_of_halfedge = np.empty_like(edge_id_sorted)
        edge_of_halfedge[order] = edge_id_sorted
        # first half-edge of an edge sets its orientation (counter-clockwise in face 0)
        second = ~first
        edge_faces = np.full((n_edges, 2), FILL, dtype=np.int64)
        edge_nodes = np.empty((n_edges, 2), dtype=np.int64)
        i1 = order[first]
        edge_faces[edge_id_sorted[first], 0] = face[i1]
        edge_nodes[edge_id_sorted[first], 0] = fa[i1]
        edge_nodes[edge_id_sorted[first], 1] = fb[i1]
        i2 = order[second]
        edge_faces[edge_id_sorted[second], 1] = face[i2]
        # consistently oriented faces traverse a shared edge in opposite directions
        same_dir = fa[i2] == edge_nodes[edge_id_sorted[second], 0]
        if np.any(same_dir):
            raise MeshError(f"{same_dir.sum()} edges are traversed in the same direction by both "
                            "faces (overlapping or folded faces)")
        self.edge_nodes = edge_nodes
        self.edge_faces = edge_faces
        face_edges = np.full((nf, nmax), FILL, dtype=np.int64)
        face_edges[face, local] = edge_of_halfedge
        self.face_edges = face_edges
        other = np.where(edge_faces[face_edges, 0] == np.arange(nf)[:, None],
                         edge_faces[face_edges, 1], edge_faces[face_edges, 0])
        self.face_neighbours = np.where(face_edges >= 0, other, FILL)
        ex = self.node_x[edge_nodes[:, 1]] - self.node_x[edge_nodes[:, 0]]
        ey = self.node_y[edge_nodes[:, 1]] - self.node_y[edge_nodes[:, 0]]
        self.edge_length = np.hypot(ex, ey)
        # unit normal pointing out of edge_faces[:, 0]
        self.edge_normal = np.stack([ey, -ex], axis=1) / self.edge_length[:, None]
        self.edge_x = 0.5 * (self.node_x[edge_nodes[:, 0]] + self.node_x[edge_nodes[:, 1]])
        self.edge_y = 0.5 * (self.node_y[edge_nodes[:, 0]] + self.node_y[edge_nodes[:, 1]])

    # ----------------------------------------------------------------- constructors
    @classmethod
    def regular_grid(cls, nx, ny, dx, dy=None, x0=0.0, y0=0.0, node_z=None) -> Mesh:
        """A grid of ``nx`` by ``ny`` rectangles of size ``dx`` by ``dy``, lower-left at (x0, y0).

        Faces are numbered row by row (x fastest): face ``j * nx + i``.
        """
        nx, ny = int(nx), int(ny)
        if nx < 1 or ny < 1:
            raise MeshError(f"regular grid needs nx, ny >= 1, got {nx}, {ny}")
        dy = dx if dy is None else dy
        if not (dx > 0 and dy > 0):
            raise MeshError(f"regular grid needs dx, dy > 0, got {dx}, {dy}")
        xs = x0 + dx * np.arange(nx + 1)
        ys = y0 + dy * np.arange(ny + 1)
        X, Y = np.meshgrid(xs, ys)
        nid = np.arange((nx + 1) * (ny + 1)).reshape(ny + 1, nx + 1)
        fn = np.stack([nid[:-1, :-1], nid[:-1, 1:], nid[1:, 1:], nid[1:, :-1]], axis=-1)
        z = None
        if callable(node_z):
            z = node_z(X.ravel(), Y.ravel())
        elif node_z is not None:
            z = np.broadcast_to(np.asarray(node_z, float), X.size)
        mesh = cls(X.ravel(), Y.ravel(), fn.reshape(-1, 4), node_z=z)
        mesh.grid_shape = (ny, nx)
        return mesh

    # ----------------------------------------------------------------- properties
    @property
    def n_nodes(self) -> int:
        """Number of nodes."""
        return self.node_x.shape[0]

    @property
    def n_faces(self) -> int:
        """Number of faces."""
        return self.face_nodes.shape[0]

    @property
    def n_edges(self) -> int:
        """Number of edges."""
        return self.edge_nodes.shape[0]

    @property
    def max_face_nodes(self) -> int:
        """Width of the face-node table (the most nodes of a face)."""
        return self.face_nodes.shape[1]

    @property
    def boundary_edges(self) -> np.ndarray:
        """Indices of the edges with a face on one side only."""
        return np.flatnonzero(self.edge_faces[:, 1] < 0)

    @property
    def bounds(self):
        """(xmin, ymin, xmax, ymax) of the nodes."""
        return (self.node_x.min(), self.node_y.min(), self.node_x.max(), self.node_y.max())

    def face_bed(self) -> np.ndarray | None:
        """Bed elevation on faces: the mean of the face's node elevations (None without node_z)."""
        if self.node_z is None:
            return None
        z = np.where(self.face_nodes >= 0, self.node_z[np.maximum(self.face_nodes, 0)], 0.0)
        return z.sum(axis=1) / self.face_n

    def __repr__(self):
        kinds = np.bincount(self.face_n, minlength=5)
        merged = getattr(self, "merged_nodes", (0, 0.0))
        seam = (f", {merged[0]} coincident nodes merged (closer than {merged[1]:g} x the local "
                "edge length)" if merged[0] else "")
        more = f", {kinds[5:].sum()} larger polygons" if kinds.size > 5 else ""
        return (f"<Mesh {self.n_faces} faces ({kinds[3]} triangles, {kinds[4]} quads{more}), "
                f"{self.n_nodes} nodes, {self.n_edges} edges, {self.boundary_edges.size} boundary "
                f"edges, tags {self.tag_names}{seam}>")

    # ----------------------------------------------------------------- boundary tags
    def tag_boundary(self, name: str, where) -> int:
        """Give boundary edges the tag ``name``; returns how many edges were tagged.

        ``where`` selects edges by their midpoints: a callable ``f(x, y) -> bool array``,
        a bounding box ``(xmin, ymin, xmax, ymax)``, or an (n, 2) polygon.
        """
        b = self.boundary_edges
        xm, ym = self.edge_x[b], self.edge_y[b]
        if callable(where):
            sel = np.asarray(where(xm, ym), dtype=bool)
        else:
            w = np.asarray(where, dtype=float)
            if w.shape == (4,):
                sel = (xm >= w[0]) & (xm <= w[2]) & (ym >= w[1]) & (ym <= w[3])
            elif w.ndim == 2 and w.shape[1] == 2 and w.shape[0] >= 3:
                from matplotlib.path import Path as MplPath

                sel = MplPath(w).contains_points(np.column_stack([xm, ym]), radius=1e-9)
            else:
                raise MeshError(f"tag_boundary({name!r}): 'where' must be a callable, a bounding "
                                f"box (xmin, ymin, xmax, ymax) or an (n, 2) polygon, got shape "
                                f"{w.shape}")
        if name not in self.tag_names:
            self.tag_names.append(name)
        self.edge_tag[b[sel]] = self.tag_names.index(name)
        return int(sel.sum())

    def tag_edges(self, name: str, edges) -> None:
        """Give the tag ``name`` to the given boundary edge indices."""
        edges = np.asarray(edges, dtype=np.int64)
        if np.any(self.edge_faces[edges, 1] >= 0):
            raise MeshError(f"tag_edges({name!r}): only boundary edges can be tagged")
        if name not in self.tag_names:
            self.tag_names.append(name)
        self.edge_tag[edges] = self.tag_names.index(name)

    def edges_with_tag(self, name: str) -> np.ndarray:
        """Boundary edge indices carrying tag ``name`` (empty if the tag is unknown)."""
        if name not in self.tag_names:
            return np.empty(0, dtype=np.int64)
        return np.flatnonzero(self.edge_tag == self.tag_names.index(name))

    def boundary_segments(self, tags=None) -> np.ndarray:
        """Boundary edges as segments (n, 4): x0, y0, x1, y1, optionally only the given tags."""
        b = self.boundary_edges
        if tags is not None:
            ids = [self.tag_names.index(t) for t in tags if t in self.tag_names]
            b = b[np.isin(self.edge_tag[b], ids)]
        e = self.edge_nodes[b]
        return np.column_stack([self.node_x[e[:, 0]], self.node_y[e[:, 0]],
                                self.node_x[e[:, 1]], self.node_y[e[:, 1]]])

    def faces_in_polygon(self, polygon) -> np.ndarray:
        """Boolean mask of the faces whose centroid lies in ``polygon`` [(x, y), ...]."""
        from matplotlib.path import Path as MplPath

        return MplPath(np.asarray(polygon, float)).contains_points(
            np.column_stack([self.face_x, self.face_y]))

    # ----------------------------------------------------------------- point location
    @property
    def bins(self):
        """The point-location bin grid (built on first use)."""
        if self._bins is None:
            self._bins = build_bin_grid(self.face_xmin, self.face_ymin,
                                        self.face_xmax, self.face_ymax)
        return self._bins

    def locator(self) -> Locator:
        """What point location reads (faces, neighbours, nodes, bin grid), packed once."""
        if self._locator is None:
            self._locator = Locator(self.face_nodes, self.face_n, self.face_neighbours,
                                    self.node_x, self.node_y, *self.bins.args())
        return self._locator

    def locate(self, x, y, hint=None) -> np.ndarray:
        """Face holding each point (-1 outside); ``hint`` (faces from before) makes it O(1)."""
        x = np.ascontiguousarray(x, dtype=np.float64).ravel()
        y = np.ascontiguousarray(y, dtype=np.float64).ravel()
        if hint is None:
            face = np.full(x.shape, FILL, dtype=np.int64)
        else:
            face = np.array(hint, dtype=np.int64).ravel().copy()
            face[(face < 0) | (face >= self.n_faces)] = FILL
        locate_points(x, y, face, self.locator())
        return face

    # ----------------------------------------------------------------- interpolation
    def node_interpolator(self) -> sp.csr_matrix:
        """Sparse (n_nodes, n_faces) operator: face values to node values, exact for linear fields.

        Each node value is the constant term of a least-squares linear fit to the values at the
        centroids of the faces around it (the ring of faces sharing a face with them where the
        first ring is too small or collinear, as at corners); so a field linear in x, y is
        reproduced exactly at every node, and the P1 interpolation built on it everywhere.
        """
        return self.node_operators()[0]

    def node_operators(self):
        """(value, d/dx, d/dy) sparse operators from face values to nodes (the same fits).

        The gradient operators give the slope of each node's least-squares fit: a recovered,
        continuous gradient (exact for linear fields) once interpolated P1 between nodes.
        """
        if self._node_interp is None:
            self._node_interp = lsq_node_operators(self)
        return self._node_interp


# --------------------------------------------------------------------- readers
#: CF standard names of coordinates in degrees (grid_*: a rotated pole)
GEOGRAPHIC_STANDARD_NAMES = ("longitude", "latitude", "grid_longitude", "grid_latitude")


def geographic_attribute(name, attrs):
    """``(attribute, value)`` by which a coordinate variable says it is geographic, or None.

    CF metadata only (no guess from the values): ``standard_name`` longitude / latitude, or
    ``units`` in degrees (degrees_east, degree_north, degrees...), as D-Flow FM writes the
    node coordinates of a spherical model.  ``attrs``: the variable's attributes (a dict).
    """
    standard = str(attrs.get("standard_name", "")).strip()
    if standard in GEOGRAPHIC_STANDARD_NAMES:
        return f"{name}:standard_name", standard
    units = str(attrs.get("units", "")).strip()
    if units.lower().startswith("degree"):
        return f"{name}:units", units
    return None


#: metres per unit of length, by UDUNITS name (lower case): node coordinates here, and every
#: length the adapters read (``driftlog.adapters._common.unit_factor``)
LENGTH_UNITS = {"m": 1.0, "meter": 1.0, "meters": 1.0, "metre": 1.0, "metres": 1.0,
                "cm": 0.01, "centimeter": 0.01, "centimeters": 0.01, "mm": 1e-3,
                "millimeter": 1e-3, "millimeters": 1e-3, "km": 1e3, "kilometer": 1e3,
                "kilometers": 1e3, "kilometre": 1e3, "kilometres": 1e3,
                "ft": 0.3048, "foot": 0.3048, "feet": 0.3048, "international_foot": 0.3048,
                "us_survey_foot": 1200.0 / 3937.0, "us_survey_feet": 1200.0 / 3937.0}


def length_unit_factor(where, name, attrs, error=MeshError):
    """(metres per unit, note or None) of a variable of lengths, from its ``units`` attribute.

    No ``units`` (or empty): metres.  A unit of ``LENGTH_UNITS`` other than the metre: its
    factor and a note saying what was converted; anything else is refused with ``error``
    naming ``where`` (the file), ``name:units`` and the value.  Metadata only: the values are
    never looked at.
    """
    units = str(attrs.get("units", "")).strip()
    if not units:
        return 1.0, None
    f = LENGTH_UNITS.get(" ".join(units.lower().split()))
    if f is None:
        raise error(f"{where}: {name}:units = {units!r}: not a unit of length driftlog knows "
                    "(m, km, cm, mm, ft, US_survey_foot); driftlog reads lengths in metres: "
                    "correct the attribute, or convert the file to metres")
    return f, (None if f == 1.0 else f"{name}: converted from {units!r} to m (x {f:.10g})")


def read_ugrid_mesh(path, topology: str | None = None) -> Mesh:
    """Read the 2D mesh of a UGRID NetCDF file (0- or 1-based, any ``_FillValue``).

    Node coordinates that say they are geographic (``geographic_attribute``) are refused:
    driftlog's meshes are in projected metres.  Node coordinates and node elevations in
    another unit of length (``units`` km, ft...: ``length_unit_factor``) are converted to
    metres; the mesh's ``unit_notes`` say which (the ugrid reader adds them to its notes).
    """
    import netCDF4

    path = Path(path)
    try:
        ds = netCDF4.Dataset(path)
    except (OSError, RuntimeError) as exc:
        raise MeshError(f"{path}: not a readable NetCDF file ({exc})") from None
    with ds:
        ds.set_auto_mask(False)
        topo = _find_topology(ds, path, topology)
        for attr in ("node_coordinates", "face_node_connectivity"):
            if attr not in topo.ncattrs():
                raise MeshError(f"{path}: mesh topology {topo.name!r} lacks the attribute {attr!r}")
        xname, yname = topo.node_coordinates.split()[:2]
        fname = topo.face_node_connectivity
        for v in (xname, yname, fname):
            if v not in ds.variables:
                raise MeshError(f"{path}: variable {v!r} named by {topo.name!r} is missing")
        factors, notes = {}, []
        for v in (xname, yname):
            var = ds.variables[v]
            attrs = {k: var.getncattr(k) for k in var.ncattrs()}
            geo = geographic_attribute(v, attrs)
            if geo is not None:
                raise geographic_error(path, *geo, error=MeshError)
            factors[v], note = length_unit_factor(path, v, attrs)
            notes += [note] if note else []
        fv = ds.variables[fname]
        fill = fv.getncattr("_FillValue") if "_FillValue" in fv.ncattrs() else FILL
        start = int(fv.getncattr("start_index")) if "start_index" in fv.ncattrs() else 0
        face_nodes = fv[:]
        fdim = topo.getncattr("face_dimension") if "face_dimension" in topo.ncattrs() else None
        if fdim is not None and fv.dimensions[-1] == fdim:  # stored (max_nodes, faces)
            face_nodes = face_nodes.T
        z = None
        for name, var in ds.variables.items():
            attrs = var.ncattrs()
            if var.dimensions == ds.variables[xname].dimensions and name not in (xname, yname):
                named = name.endswith(("node_z", "node_bed_level"))
                if named or ("location" in attrs and var.getncattr("location") == "node"):
                    vat = {k: var.getncattr(k) for k in attrs}
                    unit = " ".join(str(vat.get("units", "")).lower().split())
                    if not named and unit and unit not in LENGTH_UNITS:
                        continue  # another node variable (not a length): not the bed
                    fz, note = length_unit_factor(path, name, vat)
                    notes += [note] if note else []
                    z = var[:].astype(float) * fz
                    break
        node_x = np.asarray(ds.variables[xname][:], np.float64) * factors[xname]
        node_y = np.asarray(ds.variables[yname][:], np.float64) * factors[yname]
    for name, a in ((xname, node_x), (yname, node_y)):
        bad = np.flatnonzero(~np.isfinite(a))
        if bad.size:
            raise MeshError(f"{path}: the node coordinate {name}[{int(bad[0])}] = "
                            f"{a[bad[0]]}: node coordinates must be finite numbers "
                            f"({bad.size} of {a.size} are not)")
    mesh = mesh_merging_seams(node_x, node_y, face_nodes, fill_value=int(fill),
                              start_index=start, node_z=z)
    mesh.unit_notes = notes
    return mesh


def mesh_merging_seams(node_x, node_y, face_nodes, fill_value=FILL, start_index=0,
                       node_z=None, rel_tol=SEAM_TOLERANCE) -> Mesh:
    """A ``Mesh`` with coincident nodes merged (``merge_coincident_nodes``).

    The mesh's ``merged_nodes`` = (nodes removed, rel_tol) is shown by its repr (``driftlog
    info``); ``node_index`` maps its nodes to the given ones (for node-located data).
    """
    node_x, node_y = _as_points(node_x, "node_x"), _as_points(node_y, "node_y")
    keep, fn, n_merged = merge_coincident_nodes(node_x, node_y, face_nodes, fill_value,
                                                start_index, rel_tol)
    x = np.asarray(node_x, np.float64)[keep]
    y = np.asarray(node_y, np.float64)[keep]
    z = None if node_z is None else np.asarray(node_z, np.float64)[keep]
    mesh = Mesh(x, y, fn, node_z=z)
    mesh.merged_nodes = (n_merged, rel_tol)
    mesh.node_index = keep
    return mesh


def _find_topology(ds, path, name):
    tops = [v for v in ds.variables.values()
            if "cf_role" in v.ncattrs() and v.getncattr("cf_role") == "mesh_topology"
            and int(getattr(v, "topology_dimension", 2)) == 2]
    if name is not None:
        tops = [v for v in tops if v.name == name]
    if not tops:
        raise MeshError(f"{path}: no 2D UGRID mesh topology (a variable with cf_role = "
                        f"'mesh_topology' and topology_dimension = 2)" +
                        (f" named {name!r}" if name else ""))
    return tops[0]


def read_mesh(path, **kwargs) -> Mesh:
    """Read a mesh from UGRID NetCDF (``.nc``) or any format meshio reads (triangles and quads).

    Bed elevation comes from ``node_z`` (UGRID), or from meshio's point data named ``z``,
    ``elevation``, ``bed`` or ``bed_level``, or from a non-zero third coordinate.  Line cells with
    gmsh physical names tag the boundary edges they cover.
    """
    from driftlog.files import require

    path = Path(path)
    if not path.is_file():
        raise MeshError(f"{path}: mesh file not found")
    fk = require(path, ("mesh", "flow", "model_output", "netcdf", "ensemble", "mesh_file",
                        "text"), "mesh file", error=MeshError,
                 expected="a UGRID NetCDF file or a mesh format meshio reads")
    if fk.kind != "mesh_file" and fk.kind != "text":
        return read_ugrid_mesh(path, **kwargs)
    if path.suffix.lower() in (".nc", ".nc4", ".cdf"):
        return read_ugrid_mesh(path, **kwargs)
    import meshio

    try:
        m = meshio.read(path)
    except (Exception, SystemExit) as exc:  # meshio raises many types (ansys: SystemExit)
        raise MeshError(f"{path}: meshio cannot read it ({type(exc).__name__}: {exc})") from None
    polys, unsupported = [], []
    for block in m.cells:
        if block.type == "triangle":
            polys.append(np.column_stack([block.data, np.full(len(block.data), FILL)]))
        elif block.type == "quad":
            polys.append(block.data)
        elif block.type not in ("line", "vertex", "line3"):
            unsupported.append(block.type)
    if unsupported:
        raise MeshError(f"{path}: unsupported element types {sorted(set(unsupported))}; "
                        "driftlog reads 'triangle' and 'quad' cells")
    if not polys:
        raise MeshError(f"{path}: no triangle or quad cells")
    width = max(p.shape[1] for p in polys)
    fn = np.concatenate([np.pad(p, ((0, 0), (0, width - p.shape[1])), constant_values=FILL)
                         for p in polys])
    pts = m.points
    z = None
    for key in ("z", "elevation", "bed", "bed_level"):
        if key in m.point_data:
            z = np.asarray(m.point_data[key], float).ravel()
            break
    if z is None and pts.shape[1] > 2 and np.any(pts[:, 2] != 0):
        z = pts[:, 2]
    mesh = Mesh(pts[:, 0], pts[:, 1], fn, node_z=z)
    _tag_from_physical_lines(mesh, m)
    return mesh


def _tag_from_physical_lines(mesh, m):
    names = {int(v[0]): k for k, v in (m.field_data or {}).items() if len(v) > 1 and v[1] == 1}
    phys = m.cell_data.get("gmsh:physical")
    if not names or phys is None:
        return
    key = {}
    e = mesh.edge_nodes
    for i, (lo, hi) in enumerate(zip(np.minimum(e[:, 0], e[:, 1]), np.maximum(e[:, 0], e[:, 1]),
                                     strict=True)):
        if mesh.edge_faces[i, 1] < 0:
            key[(lo, hi)] = i
    for block, tags in zip(m.cells, phys, strict=False):
        if block.type != "line":
            continue
        for (a, b), t in zip(block.data, tags, strict=False):
            i = key.get((min(a, b), max(a, b)))
            if i is not None and int(t) in names:
                mesh.tag_edges(names[int(t)], [i])
