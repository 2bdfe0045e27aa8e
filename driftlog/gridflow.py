"""Flow on a regular grid (CF grids, rasters), sampled bilinearly between the grid's points.

A regular grid holds its values at points ``(x0 + (i + 1/2) dx, y0 + (j + 1/2) dy)``, the
centres of the ``nx`` by ``ny`` cells of the grid whose lower-left corner is ``(x0, y0)``
(cell-centred data, ``layout = "cell"``: CF grids, LISFLOOD-FP and GeoTIFF rasters), or at
the corners ``(x0 + i dx, y0 + j dy)`` of (nx - 1) by (ny - 1) cells (node-based data,
``layout = "node"``: a GeoTIFF whose AREA_OR_POINT is Point; the domain is then the hull of
the points, and the field's mesh has the points as its nodes).  ``GridFlowField`` samples
them as the grid's own interpolant, with no triangulation:

- space: bilinear between the four points around the sample point.  In the outer half cell
  of a cell-centred grid (between the outermost points and the domain's edge) the value is
  held constant across the edge (the bilinear interpolant with the coordinate clamped to the
  outermost points), so the field never overshoots there;
- velocity gradient and free-surface slope: the derivatives of that same bilinear interpolant
  (so ``dU/dx`` is what integrating the interpolated velocity sees; zero across the edge in
  the outer half cell, where the interpolant is constant in that direction);
- time: linear between the two snapshots around t, and ``dU/dt`` the slope of that linear
  interpolation (the bilinear interpolation of the snapshots' difference over their gap).

Wet and dry, as the mesh field (``driftlog.flow.MeshFlowField``) does it: on each grid point
the velocity is hu / h where h > ``dry_depth`` and 0 elsewhere, the four columns h, u, v and
the water level are interpolated on their own, and a sample is wet where the interpolated depth
exceeds ``dry_depth``.  Land (cells the source marks with fill values, read with ``fill =
'dry'``) is dry ground: depth 0, velocity 0; logs reaching it ground (resting or stranded) in
the shallowing water at its shore, as at the dry faces of a mesh.

The field is a ``MeshFlowField`` on ``Mesh.regular_grid`` (face ``j * nx + i`` is cell (row j,
column i); built lazily, ``LazyGridMesh``, as sampling does not need it), so everything built
on faces works unchanged: the face arrays of snapshots (for a node-based grid, each cell's
mean of its four corners, as for any node-located source), flow files written from it
(``driftlog import``), ``freeze``, location hints (the cell holding the point) and contact
walls, which are the grid's outer edges (tagged as on any mesh).  Land cells are not walls: a
log drifting towards land grounds in the shallowing water, as on a mesh whose dry faces are
part of the mesh (tests/test_grid_flow.py).
"""

from __future__ import annotations

import numba as nb
import numpy as np

from driftlog._numba import kernel
from driftlog.columns import DRY, G_ETA, G_H, G_U, G_V, NG, NVAR, OUTSIDE, WET
from driftlog.errors import FlowFileError
from driftlog.flow import InMemorySnapshots, MeshFlowField
from driftlog.mesh import Mesh

__all__ = ["GridFlowField", "LazyGridMesh", "sample_grid_kernel", "grid_point"]

# grid point columns of one snapshot: driftlog.columns G_H, G_U, G_V, G_ETA (NG)


@nb.njit(cache=True, inline="always")
def _axis(s, n):
    """Lower and upper point index along one axis, the upper one's weight, and 1 or 0.

    The last value is 1 where the interpolant varies along this axis at s, 0 in the outer half
    cells; s is the position in point spacings from the first point, n the number of points.
    """
    if s <= 0.0:
        return 0, 0, 0.0, 0.0
    if s >= n - 1:
        return n - 1, n - 1, 0.0, 0.0
    i0 = int(s)
    return i0, i0 + 1, s - i0, 1.0


@nb.njit(cache=True, inline="always")
def _bilinear(vals, q, p00, p10, p01, p11, s, r, kx, ky, a, b, inv_dt):
    """Value, d/dx, d/dy and d/dt of column q at the point of weights (s, r)."""
    c00 = b * vals[p00, q] + a * vals[p00, q + NG]
    c10 = b * vals[p10, q] + a * vals[p10, q + NG]
    c01 = b * vals[p01, q] + a * vals[p01, q + NG]
    c11 = b * vals[p11, q] + a * vals[p11, q + NG]
    v = (1.0 - r) * ((1.0 - s) * c00 + s * c10) + r * ((1.0 - s) * c01 + s * c11)
    gx = kx * ((1.0 - r) * (c10 - c00) + r * (c11 - c01))
    gy = ky * ((1.0 - s) * (c01 - c00) + s * (c11 - c10))
    d00 = vals[p00, q + NG] - vals[p00, q]
    d10 = vals[p10, q + NG] - vals[p10, q]
    d01 = vals[p01, q + NG] - vals[p01, q]
    d11 = vals[p11, q + NG] - vals[p11, q]
    td = inv_dt * ((1.0 - r) * ((1.0 - s) * d00 + s * d10) + r * ((1.0 - s) * d01 + s * d11))
    return v, gx, gy, td


@nb.njit(cache=True, inline="always")
def grid_point(x, y, a, inv_dt, vals, dry_depth, nx, ny, x0, y0, dx, dy, node):
    """Sample one point: (cell, flag, values) with values the NVAR columns as a tuple.

    ``vals`` (nx ny, 2 NG): the grid points' columns h, u, v, eta at the earlier snapshot, then
    at the later one (point ``j nx + i``); ``a`` the weight of the later one.  ``(x0, y0)``:
    the lower-left corner of the domain; cell-centred (``node`` False): nx by ny cells, the
    points at their centres; node-based: (nx - 1) by (ny - 1) cells, the points at their
    corners, the first one at (x0, y0).
    """
    fx = (x - x0) / dx
    fy = (y - y0) / dy
    cx, cy = (nx - 1, ny - 1) if node else (nx, ny)
    if not (fx >= 0.0 and fx <= cx and fy >= 0.0 and fy <= cy):
        return -1, OUTSIDE, (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    cell = min(int(fy), cy - 1) * cx + min(int(fx), cx - 1)
    shift = 0.0 if node else 0.5
    i0, i1, s, kx = _axis(fx - shift, nx)
    j0, j1, r, ky = _axis(fy - shift, ny)
    kx /= dx
    ky /= dy
    p00, p10, p01, p11 = j0 * nx + i0, j0 * nx + i1, j1 * nx + i0, j1 * nx + i1
    b = 1.0 - a
    h, _, _, _ = _bilinear(vals, G_H, p00, p10, p01, p11, s, r, kx, ky, a, b, inv_dt)
    u, ux, uy, ut = _bilinear(vals, G_U, p00, p10, p01, p11, s, r, kx, ky, a, b, inv_dt)
    v, vx, vy, vt = _bilinear(vals, G_V, p00, p10, p01, p11, s, r, kx, ky, a, b, inv_dt)
    e, ex, ey, _ = _bilinear(vals, G_ETA, p00, p10, p01, p11, s, r, kx, ky, a, b, inv_dt)
    h = max(h, 0.0)
    # in the column order H, U, V, DUDT, DVDT, DUDX, DUDY, DVDX, DVDY, DETADX, DETADY, ETA
    return cell, (WET if h > dry_depth else DRY), (h, u, v, ut, vt, ux, uy, vx, vy, ex, ey, e)


@kernel(nrt=False)
def sample_grid_kernel(px, py, face, out, flag, a, inv_dt, vals, dry_depth, nx, ny, x0, y0,
                       dx, dy, node):
    """Sample n points of a regular grid (``grid_point`` for each); ``face`` gets the cells."""
    for k in nb.prange(px.shape[0]):
        c, fl, res = grid_point(px[k], py[k], a, inv_dt, vals, dry_depth, nx, ny, x0, y0,
                                dx, dy, node)
        face[k] = c
        flag[k] = fl
        for q in range(NVAR):
            out[k, q] = res[q]


class LazyGridMesh:
    """The ``Mesh`` of a regular grid, built on first use of anything but its sizes.

    Sampling a grid needs no mesh (the cell of a point is arithmetic), while building the
    topology of 1e6 quadrilaterals takes seconds and hundreds of MB; the mesh is made when
    walls, plots, a flow file or point location ask for it (every attribute of ``Mesh`` is
    forwarded to it then).  ``n_faces``, ``n_nodes``, ``face_nodes``, ``face_n``, ``bounds``
    and ``grid_shape`` are answered without it.
    """

    def __init__(self, nx, ny, dx, dy, x0=0.0, y0=0.0):
        self._args = (int(nx), int(ny), float(dx), float(dy), float(x0), float(y0))
        self._mesh = None
        self._table = None
        self.n_faces = self._args[0] * self._args[1]
        self.n_nodes = (self._args[0] + 1) * (self._args[1] + 1)
        self.grid_shape = (self._args[1], self._args[0])

    @property
    def built(self) -> bool:
        """Whether the mesh has been built."""
        return self._mesh is not None

    def materialize(self) -> Mesh:
        """The ``Mesh`` itself (built once)."""
        if self._mesh is None:
            nx, ny, dx, dy, x0, y0 = self._args
            self._mesh = Mesh.regular_grid(nx, ny, dx, dy, x0=x0, y0=y0)
        return self._mesh

    def _face_table(self):
        if self._mesh is not None:
            return self._mesh.face_nodes, self._mesh.face_n
        if self._table is None:  # as Mesh.regular_grid numbers them (counter-clockwise)
            nx, ny = self._args[:2]
            nid = np.arange(self.n_nodes).reshape(ny + 1, nx + 1)
            fn = np.stack([nid[:-1, :-1], nid[:-1, 1:], nid[1:, 1:], nid[1:, :-1]], axis=-1)
            self._table = (fn.reshape(-1, 4), np.full(self.n_faces, 4, np.int64))
        return self._table

    @property
    def bounds(self):
        """(xmin, ymin, xmax, ymax) of the nodes."""
        nx, ny, dx, dy, x0, y0 = self._args
        return (x0, y0, x0 + nx * dx, y0 + ny * dy)

    face_nodes = property(lambda self: self._face_table()[0], doc="face-node table")
    face_n = property(lambda self: self._face_table()[1], doc="nodes per face (4)")

    def __getattr__(self, name):
        if name.startswith("__") or name in ("_args", "_mesh", "_table"):
            raise AttributeError(name)
        return getattr(self.materialize(), name)

    def __repr__(self):
        if self._mesh is not None:
            return repr(self._mesh)
        nx, ny = self._args[:2]
        edges = nx * (ny + 1) + ny * (nx + 1)
        return (f"<Mesh {self.n_faces} faces (0 triangles, {self.n_faces} quads), "
                f"{self.n_nodes} nodes, {edges} edges, {2 * (nx + ny)} boundary edges, "
                "tags ['wall']>")


class GridFlowField(MeshFlowField):
    """Flow on a regular grid, sampled bilinearly between the grid's points.

    Parameters
    ----------
    nx, ny : int
        Grid points (values) along x and y.
    dx, dy : float
        Point spacing (m).
    x0, y0 : float
        Lower-left corner of the domain (m).  ``layout = "cell"``: the points are the centres
        of nx by ny cells, the first at (x0 + dx/2, y0 + dy/2); ``"node"``: the points are the
        corners of (nx - 1) by (ny - 1) cells, the first at (x0, y0).
    bed : array (ny nx,)
        Bed elevation at the points (m), row by row from the south (x fastest).
    source : object with ``times`` and ``read(i) -> (h, hu, hv)``
        Snapshots as arrays (ny nx,) in the same order (lazily read); for ``"node"`` its
        ``location`` is ``"node"`` (the points are the mesh's nodes).
    dry_depth : float
        Depth (m) below which a point is dry: velocity 0 there, samples flagged dry.
    layout : 'cell' or 'node'
        Where the values sit (see x0, y0): the domain is the cells around the points, or the
        cells between them.
    name, attrs
        As for ``MeshFlowField``.
    """

    def __init__(self, nx, ny, dx, dy, x0, y0, bed, source, dry_depth=1e-3, name=None,
                 attrs=None, mesh=None, layout="cell"):
        nx, ny, dx, dy = int(nx), int(ny), float(dx), float(dy)
        where = name or "grid"
        if layout not in ("cell", "node"):
            raise FlowFileError(f"{where}: layout = {layout!r}: must be 'cell' or 'node'")
        least = 2 if layout == "node" else 1
        if nx < least or ny < least or not (dx > 0 and dy > 0):
            raise FlowFileError(f"{where}: a grid needs nx, ny >= {least} points "
                                f"({layout} layout) and dx, dy > 0, got {nx}, {ny}, {dx}, {dy}")
        if layout == "node" and getattr(source, "location", "face") != "node":
            raise FlowFileError(f"{where}: node layout needs a source with location = 'node'")
        if layout == "cell" and getattr(source, "location", "face") != "face":
            raise FlowFileError(f"{where}: cell layout needs a source of cell (face) values")
        self.grid = (nx, ny, float(x0), float(y0), dx, dy)
        self.layout = layout
        if mesh is None:  # built when something needs it (walls, plots, flow files)
            cx, cy = (nx - 1, ny - 1) if layout == "node" else (nx, ny)
            mesh = LazyGridMesh(cx, cy, dx, dy, x0=x0, y0=y0)
        super().__init__(mesh, bed, source, dry_depth=dry_depth, name=name, attrs=attrs,
                         gradient="p1")
        self.gradient = "bilinear"

    @property
    def grid_shape(self):
        """(ny, nx) points."""
        return self.grid[1], self.grid[0]

    def point_coordinates(self):
        """x, y of the grid points (cell centres, or cell corners), arrays (ny nx,)."""
        nx, ny, x0, y0, dx, dy = self.grid
        shift = 0.0 if self.layout == "node" else 0.5
        X, Y = np.meshgrid(x0 + dx * (np.arange(nx) + shift), y0 + dy * (np.arange(ny) + shift))
        return X.ravel(), Y.ravel()

    def _load(self, i, gradients=True):
        """The base class's, on the grid's columns (``gradients``: none to leave out)."""
        if i in self._snap:
            self._snap.move_to_end(i)
            return self._snap[i]
        if self.layout == "node":
            h, hu, hv = self.read_source(i)
            bed = self.node_bed
        else:
            h, hu, hv = self.read_snapshot(i)
            bed = self.bed
        u, v = self._velocity(h, hu, hv)
        vals = np.empty((h.size, NG))
        vals[:, G_H], vals[:, G_U], vals[:, G_V], vals[:, G_ETA] = h, u, v, h + bed
        if self.layout == "node":  # face arrays: each cell's corner mean (as the base class)
            A = self._face_mean
            h, hu, hv = A @ h, A @ hu, A @ hv
        self._snap[i] = (h, hu, hv, vals)
        while len(self._snap) > 2:
            self._snap.popitem(last=False)
        return self._snap[i]

    def mesh_kernel(self):
        """None: no fused mesh kernel (the tracker takes the general path).

        The grid is sampled bilinearly (``sample_grid_kernel``), not P1 on mesh nodes.
        """
        return None

    def sample_into(self, x, y, t, face, out, flag):
        """Kernel entry: fill ``out`` (n, NVAR) and ``flag`` (n,); ``face`` gets the cells."""
        vals, a, inv_dt = self.node_values(t)
        nx, ny, x0, y0, dx, dy = self.grid
        sample_grid_kernel(x, y, face, out, flag, a, inv_dt, vals, self.dry_depth, nx, ny, x0,
                           y0, dx, dy, self.layout == "node")

    def freeze(self, t) -> GridFlowField:
        """The flow at time t as a steady field (one snapshot) on the same grid."""
        nx, ny, x0, y0, dx, dy = self.grid
        name = f"{self.name} at t={t}"
        if self.layout == "node":
            i, j, a, _ = self._interval(t)
            si, sj = self.read_source(i), self.read_source(j)
            h, hu, hv = ((1 - a) * p + a * q for p, q in zip(si, sj, strict=True))
            src = InMemorySnapshots([t], h, hu, hv, name=name, location="node")
            bed = self.node_bed
        else:
            fv = self.face_values(t)
            src = InMemorySnapshots([t], fv["h"], fv["hu"], fv["hv"], name=name)
            bed = self.bed
        return GridFlowField(nx, ny, dx, dy, x0, y0, bed, src, self.dry_depth,
                             attrs=self.attrs, mesh=self.mesh, layout=self.layout)

    @classmethod
    def from_arrays(cls, nx, ny, dx, dy, x0, y0, bed, times, h, hu, hv, layout="cell",
                    **kwargs):
        """A grid field from arrays (n_times, ny nx) held in memory."""
        src = InMemorySnapshots(times, h, hu, hv, kwargs.get("name", "grid flow"),
                                location="node" if layout == "node" else "face")
        return cls(nx, ny, dx, dy, x0, y0, bed, src, layout=layout, **kwargs)

    def __repr__(self):
        nx, ny, x0, y0, dx, dy = self.grid
        t0, t1 = self._times[0], self._times[-1]
        where = "cell centres" if self.layout == "cell" else "cell corners"
        return (f"<GridFlowField {self.name!r}: {ny} x {nx} values at the {where} of "
                f"{dx:g} x {dy:g} m cells from ({x0:g}, {y0:g}), {self._times.size} snapshots "
                f"from {t0} to {t1} s>")
