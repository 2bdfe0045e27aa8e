"""HEC-RAS 2D results (HEC-RAS 6.x plan and geometry HDF5 files) as driftlog flows.

A HEC-RAS 2D flow area is a mesh of polygonal cells (3 to 8 sides; HEC-RAS's ``Cells FacePoint
Indexes`` pads with -1) whose faces join *face points*.  The plan output stores, per output
time, the ``Water Surface`` of each cell and the ``Face Velocity``: the velocity normal to each
face (HEC-RAS stores no cell velocity vector; RAS Mapper reconstructs one).  This reader:

- builds each cell's polygon from its faces (``Cells Face and Orientation``), face points and
  the intermediate points of perimeter faces (``Faces Perimeter Values``), so the polygon's area
  is HEC-RAS's own ``Cells Surface Area``.  A cell whose polygon is convex with at most 8 nodes
  is one driftlog mesh face; a non-convex perimeter cell (or one with more nodes) is split into
  triangles (ear clipping) that all carry the cell's values;
- reads every 2D flow area in the file, or those named (option ``areas``), into one mesh;
- takes the bed from ``Cells Minimum Elevation`` (the cell's lowest terrain point, HEC-RAS's
  own bed), in the plan or in a geometry file the user names (option ``geometry``), or from a
  terrain raster the user names (option ``terrain``: the lowest raster pixel in each cell); a
  plan without any of these is an error that says which option to give.  ``bed =
  "min_water_surface"`` takes the plan's summary ``Minimum Water Surface`` instead: exact for
  cells that went dry during the run (HEC-RAS reports a dry cell's water surface at its
  minimum elevation), above the bed for cells wet throughout; a documented approximation the
  user must ask for;
- depth = water surface - bed (a float32 round-off below the bed is clipped; more is an error);
- reconstructs the cell velocity from the faces' normal velocities by least squares over the
  cell's faces weighted by face length: ``(sum L n n^T) u = sum L n v_n``, exact for a uniform
  flow, applied as two precomputed sparse operators (one matrix product per snapshot);
- reads the time axis from ``Time Date Stamp`` (times in seconds since the first stamp, kept as
  ``attrs["time_reference"] = "seconds since YYYY-MM-DDTHH:MM:SS"``);
- converts US Customary files (ft, ft/s) to SI, coordinates included (x_m = 0.3048 x_ft), and
  keeps the projection (WKT) and the factor in the flow's attributes.

The plan's time series may sit in a separate file (the option ``results``), as in the trimmed
Bald Eagle Creek example of ``../shared/data/hecras``.
"""

from __future__ import annotations

import datetime as _dt
import re
from dataclasses import dataclass, field
from pathlib import Path

import numba as nb
import numpy as np
import scipy.sparse as sp

from driftlog.errors import FlowFileError, MeshError
from driftlog.schema import Key

__all__ = ["KIND", "SUFFIXES", "OPTIONS", "can_open", "open", "open_hecras", "describe",
           "read_geometry", "HecrasGeometry", "FT"]

KIND = "hecras"
SUFFIXES = (".hdf", ".h5", ".hdf5")
FT = 0.3048  # international foot (HEC-RAS US Customary lengths) in metres
MAX_SIDES = 8  # cells with more nodes (perimeter points) are split into triangles

_AREAS = "Geometry/2D Flow Areas"
_OUTPUT = "Results/Unsteady/Output/Output Blocks/Base Output"
_SERIES = _OUTPUT + "/Unsteady Time Series"
_SUMMARY = _OUTPUT + "/Summary Output/2D Flow Areas"
_HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"

OPTIONS = [
    Key("areas", "any", None, "2D flow areas to read: a name or a list of names (default: all "
        "of the file's)"),
    Key("bed", "str", "auto", "'auto': Cells Minimum Elevation of the plan, else of the "
        "'geometry' file, else the lowest pixel of 'terrain' in each cell (an error if none); "
        "'min_water_surface': the lowest water surface the plan reports per cell (the bed where "
        "a cell went dry, above it elsewhere)", choices=("auto", "min_water_surface")),
    Key("geometry", "path", None, "HEC-RAS geometry HDF (*.gNN.hdf) whose Cells Minimum "
        "Elevation is the bed, when the plan file lacks it", must_exist=True),
    Key("terrain", "path", None, "terrain raster (GeoTIFF...) in the project's coordinates and "
        "units: the bed is its lowest pixel in each cell (needs rasterio)", must_exist=True),
    Key("results", "path", None, "HDF file holding the plan's 'Unsteady Time Series' when the "
        "plan file given has none", must_exist=True),
]

# --------------------------------------------------------------------- small helpers
def _s(v) -> str:
    """An HDF5 attribute or string value as text."""
    if isinstance(v, np.ndarray) and v.size == 1:
        v = v.ravel()[0]
    if isinstance(v, (bytes, np.bytes_)):
        return v.decode("utf-8", "replace").strip()
    return str(v).strip()


def can_open(path) -> bool:
    """Whether ``path`` is a HEC-RAS HDF5 file (cheap sniff; never raises)."""
    try:
        p = Path(path)
        if not p.is_file():
            return False
        with p.open("rb") as fh:
            if fh.read(8) != _HDF5_SIGNATURE:
                return False
        import h5py

        with h5py.File(p, "r") as f:
            return _s(f.attrs.get("File Type", b"")).startswith("HEC-RAS") or _AREAS in f
    except Exception:  # a sniff never raises
        return False


def _open_h5(path, what="HEC-RAS file"):
    import h5py

    p = Path(path)
    if not p.is_file():
        raise FlowFileError(f"{p}: {what} not found")
    with p.open("rb") as fh:
        head = fh.read(8)
    if head != _HDF5_SIGNATURE:
        raise FlowFileError(f"{p}: not a HEC-RAS file (not HDF5: HEC-RAS 6 writes plan and "
                            "geometry results as HDF5, *.pNN.hdf / *.gNN.hdf)")
    try:
        return h5py.File(p, "r")
    except OSError as exc:
        msg = str(exc)
        why = "truncated or damaged" if "truncated" in msg or "eof" in msg else "unreadable"
        raise FlowFileError(f"{p}: {why} HDF5 file ({msg})") from None


def _read(f, key, path):
    """A dataset's values; a damaged (truncated) file gives a FlowFileError."""
    try:
        return f[key][()]
    except KeyError:
        raise FlowFileError(f"{path}: dataset {key!r} is missing") from None
    except OSError as exc:
        raise FlowFileError(f"{path}: cannot read {key!r}: the file is truncated or damaged "
                            f"({exc})") from None


def _area_table(f, path):
    """(names, real cell counts) of the 2D flow areas of an open HEC-RAS file."""
    if _AREAS not in f:
        ftype = _s(f.attrs.get("File Type", b""))
        kind = f"a {ftype!r} file" if ftype else "an HDF5 file"
        raise FlowFileError(f"{path}: not a HEC-RAS 2D file: {kind} without the group "
                            f"{_AREAS!r} (no 2D flow area)")
    g = f[_AREAS]
    if "Attributes" in g:
        att = _read(f, _AREAS + "/Attributes", path)
        names = [_s(n) for n in att["Name"]]
        counts = [int(c) for c in att["Cell Count"]] if "Cell Count" in att.dtype.names else None
    else:
        names = [k for k in g if isinstance(g[k], type(g)) and "FacePoints Coordinate" in g[k]]
        counts = None
    if counts is None:  # real cells come first; virtual (ghost) cells have one face
        counts = []
        for n in names:
            info = _read(f, f"{_AREAS}/{n}/Cells Face and Orientation Info", path)
            counts.append(int(np.argmin(np.append(info[:, 1] >= 3, False))))
    if not names:
        raise FlowFileError(f"{path}: the HEC-RAS file has no 2D flow area")
    return names, counts


def _select_areas(names, areas, path):
    if areas is None:
        return list(range(len(names)))
    if isinstance(areas, str):
        areas = [areas]
    out = []
    for a in areas:
        if a not in names:
            raise FlowFileError(f"{path}: no 2D flow area named {a!r}; the file has "
                                f"{', '.join(repr(n) for n in names)}")
        out.append(names.index(a))
    return out


# --------------------------------------------------------------------- polygon kernels
@nb.njit(cache=True)
def _ear_clip(start, ids, x, y, tri, owner):
    """Triangulate simple counter-clockwise polygons (ids[start[p]:start[p+1]]) by ear clipping.

    Writes triangles into ``tri`` (n, 3) and their polygon into ``owner``; returns the count,
    or -1 - p when polygon p cannot be split (self-intersecting or degenerate).
    """
    t = 0
    work = np.empty(ids.size, np.int64)
    for p in range(start.size - 1):
        s, e = start[p], start[p + 1]
        m = e - s
        for k in range(m):
            work[k] = ids[s + k]
        while m > 3:
            found = False
            for i in range(m):
                a = work[(i - 1) % m]
                b = work[i]
                c = work[(i + 1) % m]
                cr = (x[b] - x[a]) * (y[c] - y[b]) - (y[b] - y[a]) * (x[c] - x[b])
                if cr <= 0.0:
                    continue
                inside = False
                for j in range(m):
                    q = work[j]
                    if q == a or q == b or q == c:
                        continue
                    d1 = (x[b] - x[a]) * (y[q] - y[a]) - (y[b] - y[a]) * (x[q] - x[a])
                    d2 = (x[c] - x[b]) * (y[q] - y[b]) - (y[c] - y[b]) * (x[q] - x[b])
                    d3 = (x[a] - x[c]) * (y[q] - y[c]) - (y[a] - y[c]) * (x[q] - x[c])
                    if d1 >= 0.0 and d2 >= 0.0 and d3 >= 0.0:
                        inside = True
                        break
                if inside:
                    continue
                tri[t, 0], tri[t, 1], tri[t, 2] = a, b, c
                owner[t] = p
                t += 1
                for k in range(i, m - 1):
                    work[k] = work[k + 1]
                m -= 1
                found = True
                break
            if not found:
                return -1 - p
        a, b, c = work[0], work[1], work[2]
        if (x[b] - x[a]) * (y[c] - y[b]) - (y[b] - y[a]) * (x[c] - x[b]) <= 0.0:
            return -1 - p
        tri[t, 0], tri[t, 1], tri[t, 2] = a, b, c
        owner[t] = p
        t += 1
    return t


@nb.njit(cache=True)
def _turn_kernel(start, ids, x, y, out):
    for p in range(start.size - 1):
        s, e = start[p], start[p + 1]
        n = e - s
        for k in range(n):
            a = ids[s + (k - 1) % n]
            b = ids[s + k]
            c = ids[s + (k + 1) % n]
            ax, ay = x[b] - x[a], y[b] - y[a]
            bx, by = x[c] - x[b], y[c] - y[b]
            norm = max(np.sqrt((ax * ax + ay * ay) * (bx * bx + by * by)), 1e-300)
            out[s + k] = (ax * by - ay * bx) / norm


def _turns(start, ids, x, y):
    """Sine of the turn at each polygon node (left > 0), flat like ``ids``, and its polygon."""
    start = np.ascontiguousarray(start, np.int64)
    out = np.empty(ids.size)
    _turn_kernel(start, np.ascontiguousarray(ids, np.int64), np.ascontiguousarray(x, float),
                 np.ascontiguousarray(y, float), out)
    return out, np.repeat(np.arange(start.size - 1), np.diff(start))


def _slices(start, sel):
    """Flat indices of the slices start[c]:start[c+1] for c in sel, and their local positions."""
    n = start[sel + 1] - start[sel]
    first = np.repeat(np.cumsum(np.r_[0, n[:-1]]), n).astype(np.int64)
    local = np.arange(int(n.sum())) - first
    return np.repeat(start[sel], n) + local, local, n


# --------------------------------------------------------------------- geometry
@dataclass
class HecrasGeometry:
    """The 2D flow areas of a HEC-RAS file as one driftlog mesh, and the maps to HEC-RAS cells.

    Attributes
    ----------
    mesh : Mesh
        driftlog mesh (SI units): one face per convex cell, triangles for split cells.
    cell_of_face : ndarray (n_mesh_faces,)
        HEC-RAS cell (global index over the areas read) of each mesh face.
    areas : list of str
        Names of the areas read, in order; ``cell_start`` / ``face_start`` (len + 1) give each
        area's range of global cells / HEC-RAS faces.
    cell_area : ndarray (n_cells,)
        Area of each cell's polygon (m2).
    face_normal, face_length : ndarray (n_hec_faces, 2), (n_hec_faces,)
        Unit normal (pointing from the face's cell 0 to cell 1, HEC-RAS's convention) and
        length (m) of each HEC-RAS face.
    vel_x, vel_y : scipy.sparse.csr_matrix (n_cells, n_hec_faces)
        Least-squares reconstruction: cell velocity = (vel_x @ v_n, vel_y @ v_n).
    length_factor : float
        Metres per file length unit (0.3048 for US Customary, 1 for SI).
    """

    mesh: object
    cell_of_face: np.ndarray
    areas: list
    area_index: list
    cell_start: np.ndarray
    face_start: np.ndarray
    n_real: list
    cell_area: np.ndarray
    face_normal: np.ndarray
    face_length: np.ndarray
    vel_x: object
    vel_y: object
    length_factor: float
    attrs: dict = field(default_factory=dict)
    n_split: int = 0

    @property
    def n_cells(self) -> int:
        """Number of HEC-RAS cells read (all areas)."""
        return int(self.cell_start[-1])

    def cell_velocity(self, vn):
        """Cell velocity (u, v) from face normal velocities ``vn`` (n_hec_faces,)."""
        vn = np.asarray(vn, dtype=np.float64)
        return self.vel_x @ vn, self.vel_y @ vn


def _units(f, path):
    system = _s(f.attrs.get("Units System", b""))
    if system == "" and "Geometry" in f:
        si = _s(f["Geometry"].attrs.get("SI Units", b""))
        system = "SI Units" if si.lower() == "true" else ("US Customary" if si else "")
    if system.lower().startswith("us"):
        return FT, "US Customary"
    if system.lower().startswith("si") or system == "":
        return 1.0, system or "SI Units (assumed: no 'Units System' attribute)"
    raise FlowFileError(f"{path}: 'Units System' = {system!r} not understood (expected "
                        "'US Customary' or 'SI Units')")


def _read_area(f, path, name, ncell, factor):
    """One 2D area: polygon nodes per cell, face normals and lengths, least-squares weights.

    (A function of its own so that its many temporaries are freed before the mesh is built.)
    """
    base = f"{_AREAS}/{name}"
    fp = _read(f, base + "/FacePoints Coordinate", path).astype(np.float64) * factor
    ffp = _read(f, base + "/Faces FacePoint Indexes", path).astype(np.int64)
    info = _read(f, base + "/Cells Face and Orientation Info", path).astype(np.int64)
    vals = _read(f, base + "/Cells Face and Orientation Values", path).astype(np.int64)
    if f"{base}/Faces Perimeter Info" in f:
        pinfo = _read(f, base + "/Faces Perimeter Info", path).astype(np.int64)
        pv = _read(f, base + "/Faces Perimeter Values", path).astype(np.float64) * factor
    else:
        pinfo = np.zeros((ffp.shape[0], 2), np.int64)
        pv = np.empty((0, 2))
    nfp, nface = fp.shape[0], ffp.shape[0]
    if ncell > info.shape[0] or ffp.size and (ffp.min() < 0 or ffp.max() >= nfp):
        raise FlowFileError(f"{path}: area {name!r}: inconsistent geometry (cell count "
                            f"{ncell}, {info.shape[0]} cell rows, face points "
                            f"{nfp})")
    # (cell, face, orientation) entries of the real cells, in HEC-RAS's (ccw) order
    cnt = info[:ncell, 1]
    e_cell = np.repeat(np.arange(ncell), cnt)
    e_row = np.repeat(info[:ncell, 0] - np.cumsum(np.r_[0, cnt[:-1]]), cnt) + \
        np.arange(cnt.sum())
    e_face, e_or = vals[e_row, 0], vals[e_row, 1]
    if np.any(cnt < 3):
        bad = np.flatnonzero(cnt < 3)[:5]
        raise FlowFileError(f"{path}: area {name!r}: cells {bad.tolist()} have fewer "
                            "than 3 faces")
    # polygon nodes: each face's start point, then its perimeter points (A -> B order)
    pc = pinfo[e_face, 1]
    n_e = 1 + pc
    total = int(n_e.sum())
    e_of = np.repeat(np.arange(e_face.size), n_e)
    first = np.cumsum(np.r_[0, n_e[:-1]])
    loc = np.arange(total) - first[e_of]
    fwd = (e_or > 0)[e_of]
    start_pt = np.where(e_or > 0, ffp[e_face, 0], ffp[e_face, 1])[e_of]
    ps = pinfo[e_face, 0][e_of]
    pcount = pc[e_of]
    pidx = np.where(fwd, ps + loc - 1, ps + pcount - loc)
    node = np.where(loc == 0, start_pt, nfp + pidx)
    # drop perimeter points on a straight line (they would make a flat angle)
    ax = np.r_[fp[:, 0], pv[:, 0]]
    ay = np.r_[fp[:, 1], pv[:, 1]]
    cstart = np.r_[0, np.cumsum(np.bincount(e_cell, weights=n_e, minlength=ncell))]
    cstart = cstart.astype(np.int64)
    flat = np.zeros(node.size, bool)
    if pc.any():
        turn, poly = _turns(cstart, node, ax, ay)
        flat = (loc > 0) & (np.abs(turn) <= 1e-9)
    if np.any(flat):
        node = node[~flat]
        cstart = np.r_[0, np.cumsum(np.bincount(poly[~flat], minlength=ncell))]
    # face normals (cell 0 -> cell 1: right of A -> B) and lengths
    d = fp[ffp[:, 1]] - fp[ffp[:, 0]]
    L = np.hypot(d[:, 0], d[:, 1])
    if np.any(L <= 0):
        raise FlowFileError(f"{path}: area {name!r}: faces "
                            f"{np.flatnonzero(L <= 0)[:5].tolist()} have zero length")
    n = np.column_stack([d[:, 1], -d[:, 0]]) / L[:, None]
    # least squares per cell: (sum L n n^T) u = sum L n v_n
    nx, ny, le = n[e_face, 0], n[e_face, 1], L[e_face]
    mxx = np.bincount(e_cell, le * nx * nx, ncell)
    mxy = np.bincount(e_cell, le * nx * ny, ncell)
    myy = np.bincount(e_cell, le * ny * ny, ncell)
    det = mxx * myy - mxy * mxy
    if np.any(det <= 1e-12 * (mxx + myy) ** 2):
        bad = np.flatnonzero(det <= 1e-12 * (mxx + myy) ** 2)[:5]
        raise FlowFileError(f"{path}: area {name!r}: cells {bad.tolist()} have "
                            "parallel faces only (no velocity reconstruction)")
    ixx, ixy, iyy = myy / det, -mxy / det, mxx / det
    c = e_cell
    return dict(ax=ax, ay=ay, node=node, cstart=cstart, normal=n, length=L, cell=e_cell,
                face=e_face, wx=le * (ixx[c] * nx + ixy[c] * ny),
                wy=le * (ixy[c] * nx + iyy[c] * ny), nface=nface)


def read_geometry(path, areas=None, f=None) -> HecrasGeometry:
    """Read the 2D flow areas of a HEC-RAS plan or geometry HDF file as one driftlog mesh.

    Parameters
    ----------
    path : path
        HEC-RAS HDF5 file (plan ``.pNN.hdf`` or geometry ``.gNN.hdf``).
    areas : str or list of str, optional
        Names of the 2D flow areas to read (default: all).
    f : h5py.File, optional
        The file, already open.

    Returns
    -------
    HecrasGeometry
    """
    from driftlog.mesh import Mesh

    path = Path(path)
    own = f is None
    if own:
        f = _open_h5(path)
    try:
        names, counts = _area_table(f, path)
        sel = _select_areas(names, areas, path)
        factor, system = _units(f, path)
        xs, ys, polys_start, polys_ids, cell_start, face_start = [], [], [], [], [0], [0]
        rows, cols, wx, wy, normals, lengths = [], [], [], [], [], []
        node_off = poly_off = 0
        for ia in sel:
            name, ncell = names[ia], counts[ia]
            a = _read_area(f, path, name, ncell, factor)
            xs.append(a["ax"])
            ys.append(a["ay"])
            polys_ids.append(a["node"] + node_off)
            polys_start.append(a["cstart"][1:] + poly_off)
            poly_off += a["node"].size
            node_off += a["ax"].size
            normals.append(a["normal"])
            lengths.append(a["length"])
            rows.append(a["cell"] + cell_start[-1])
            cols.append(a["face"] + face_start[-1])
            wx.append(a["wx"])
            wy.append(a["wy"])
            nface = a["nface"]
            del a
            cell_start.append(cell_start[-1] + ncell)
            face_start.append(face_start[-1] + nface)
        nf_tot = int(face_start[-1])
        nc = int(cell_start[-1])
        r, c = np.concatenate(rows), np.concatenate(cols)
        vx = sp.csr_matrix((np.concatenate(wx), (r, c)), shape=(nc, nf_tot))
        vy = sp.csr_matrix((np.concatenate(wy), (r, c)), shape=(nc, nf_tot))
        del rows, cols, wx, wy, r, c
        node_x, node_y = np.concatenate(xs), np.concatenate(ys)
        del xs, ys
        pstart = np.concatenate([[0], *polys_start]).astype(np.int64)
        pids = np.concatenate(polys_ids).astype(np.int64)
        # compact: only the nodes used by a polygon
        used = np.zeros(node_x.size, bool)
        used[pids] = True
        remap = np.cumsum(used) - 1
        node_x, node_y, pids = node_x[used], node_y[used], remap[pids].astype(np.int64)
        del polys_ids, polys_start, used, remap
        nnode = np.diff(pstart)
        turn, poly = _turns(pstart, pids, node_x, node_y)
        convex = np.bincount(poly, turn <= 0, nc) == 0
        keep = convex & (nnode <= MAX_SIDES)
        width = int(nnode[keep].max(initial=3))
        kc = np.flatnonzero(keep)
        fn = np.full((kc.size, width), -1, np.int64)
        flat_k, lk, nk = _slices(pstart, kc)
        fn[np.repeat(np.arange(kc.size), nk), lk] = pids[flat_k]
        split = np.flatnonzero(~keep)
        owner_faces = [kc]
        blocks = [fn]
        if split.size:
            sstart = np.r_[0, np.cumsum(nnode[split])].astype(np.int64)
            sids = pids[_slices(pstart, split)[0]]
            tri = np.empty((int((nnode[split] - 2).sum()), 3), np.int64)
            own_t = np.empty(tri.shape[0], np.int64)
            nt = _ear_clip(sstart, sids, node_x, node_y, tri, own_t)
            if nt < 0:
                bad = int(split[-1 - nt])
                raise FlowFileError(f"{path}: cell {bad} (global index) has a polygon that "
                                    "cannot be split into triangles (self-intersecting)")
            blk = np.full((nt, width), -1, np.int64)
            blk[:, :3] = tri[:nt]
            blocks.append(blk)
            owner_faces.append(split[own_t[:nt]])
        face_nodes = np.concatenate(blocks)
        cell_of_face = np.concatenate(owner_faces)
        del blocks, owner_faces, fn, turn, poly, pids, flat_k, lk
        order = np.argsort(cell_of_face, kind="stable")  # mesh faces in cell order
        face_nodes = face_nodes[order]
        try:
            mesh = Mesh(node_x, node_y, face_nodes, repair=False)
        except MeshError as exc:
            raise FlowFileError(f"{path}: the HEC-RAS cells do not form a valid mesh: {exc}") \
                from None
        cell_area = np.bincount(cell_of_face[order], mesh.face_area, nc)
        attrs = {"hecras_file": str(path), "hecras_areas": ", ".join(names[i] for i in sel),
                 "hecras_units_system": system, "hecras_length_factor": factor}
        proj = f.attrs.get("Projection")
        if proj is not None and _s(proj):
            attrs["crs_wkt"] = _s(proj)
            attrs["crs_note"] = (f"x, y are the projection's coordinates x {factor} (metres)"
                                 if factor != 1.0 else "x, y are the projection's coordinates")
        return HecrasGeometry(mesh, cell_of_face[order], [names[i] for i in sel], sel,
                              np.asarray(cell_start), np.asarray(face_start),
                              [counts[i] for i in sel], cell_area, np.concatenate(normals),
                              np.concatenate(lengths), vx, vy, factor, attrs, int(split.size))
    finally:
        if own:
            f.close()


# --------------------------------------------------------------------- time axis
_STAMP = re.compile(r"^(\d{1,2})([A-Za-z]{3})(\d{4})\s+"
                    r"(\d{2}):?(\d{2})(?::?(\d{2}))?(?::(\d{1,3}))?$")
_MONTHS = {m: i for i, m in enumerate(["JAN", "FEB", "MAR", "APR", "MAY", "JUN", "JUL", "AUG",
                                       "SEP", "OCT", "NOV", "DEC"], start=1)}


def parse_stamp(text, where="time stamp") -> np.datetime64:
    """A HEC-RAS date stamp ('01JAN1999 12:00:00:000', '01JAN1999 2400') as datetime64[ms]."""
    s = _s(text)
    m = _STAMP.match(s)
    if m is None or m.group(2).upper() not in _MONTHS:
        raise FlowFileError(f"{where}: date stamp {s!r} not understood (expected "
                            "'DDMONYYYY HH:MM:SS[:mmm]', e.g. '01JAN1999 12:00:00:000')")
    day, mon, year, hh, mm, ss, ms = m.groups()
    base = np.datetime64(_dt.date(int(year), _MONTHS[mon.upper()], int(day)), "ms")
    # HEC-RAS writes midnight as 24:00 of the day before
    off = ((int(hh) * 60 + int(mm)) * 60 + int(ss or 0)) * 1000 + int((ms or "0").ljust(3, "0"))
    return base + np.timedelta64(off, "ms")


def read_time_axis(f, path):
    """(seconds since the first stamp, the first stamp as ISO text) of the time series."""
    for key in (_SERIES + "/Time Date Stamp (ms)", _SERIES + "/Time Date Stamp"):
        if key in f:
            stamps = _read(f, key, path)
            t = np.array([parse_stamp(s, f"{path}: {key}") for s in stamps])
            sec = (t - t[0]).astype("timedelta64[ms]").astype(np.int64) / 1000.0
            return sec, str(t[0].astype("datetime64[s]"))
    if _SERIES + "/Time" in f:  # days since the simulation start
        days = _read(f, _SERIES + "/Time", path).astype(np.float64)
        return (days - days[0]) * 86400.0, None
    raise FlowFileError(f"{path}: the time series has no 'Time Date Stamp' nor 'Time' dataset "
                        f"under {_SERIES!r}")


# --------------------------------------------------------------------- results
class HecrasSnapshots:
    """Lazy snapshots of a HEC-RAS time series on the driftlog mesh faces: (h, hu, hv)."""

    def __init__(self, f, path, geom, bed_cells, times, index, name):
        self.f, self.path, self.geom, self.bed_cells = f, path, geom, bed_cells
        self.times = np.asarray(times, np.float64)
        self.index = np.asarray(index, np.int64)
        self.name = name
        self.depth_tolerance = 1e-3  # m: float32 round-off of a water surface near the bed

    def cell_arrays(self, i):
        """Cell arrays (water surface, depth, u, v) of snapshot i (SI units)."""
        g, k = self.geom, int(self.index[i])
        ws, vn = [], []
        for name, nreal in zip(g.areas, g.n_real, strict=True):
            base = f"{_SERIES}/2D Flow Areas/{name}"
            try:
                ws.append(self.f[base + "/Water Surface"][k, :nreal])
                vn.append(self.f[base + "/Face Velocity"][k, :])
            except OSError as exc:
                raise FlowFileError(f"{self.path}: cannot read snapshot {k} of area {name!r}: "
                                    f"the file is truncated or damaged ({exc})") from None
        ws = np.concatenate(ws).astype(np.float64) * g.length_factor
        vn = np.concatenate(vn).astype(np.float64) * g.length_factor
        if vn.size != g.face_normal.shape[0]:
            raise FlowFileError(f"{self.path}: snapshot {k}: {vn.size} face velocities for "
                                f"{g.face_normal.shape[0]} faces")
        for arr, what in ((ws, "Water Surface"), (vn, "Face Velocity")):
            if not np.all(np.isfinite(arr)):
                bad = np.flatnonzero(~np.isfinite(arr))
                raise FlowFileError(f"{self.path}: snapshot {k}: {bad.size} non-finite "
                                    f"{what} values (first cells/faces {bad[:5].tolist()})")
        h = ws - self.bed_cells
        low = h < -self.depth_tolerance
        if np.any(low):
            bad = np.flatnonzero(low)
            raise FlowFileError(f"{self.path}: snapshot {k}: the water surface is below the bed "
                                f"in {bad.size} cells (first {bad[:5].tolist()}, by up to "
                                f"{-h.min():.3g} m): the bed does not belong to this plan")
        h = np.maximum(h, 0.0)
        u, v = g.cell_velocity(vn)
        return ws, h, u, v

    def read(self, i):
        _, h, u, v = self.cell_arrays(i)
        c = self.geom.cell_of_face
        return h[c], (h * u)[c], (h * v)[c]

    def close(self):
        try:
            self.f.close()
        except Exception:  # already closed
            pass


def _bed_from_geometry_file(gpath, geom, path):
    gf = _open_h5(gpath, "geometry file")
    with gf:
        names, counts = _area_table(gf, gpath)
        factor, _ = _units(gf, gpath)
        beds = []
        for name, nreal in zip(geom.areas, geom.n_real, strict=True):
            if name not in names:
                raise FlowFileError(f"{gpath}: no 2D flow area {name!r} (the plan {path} has "
                                    f"it); the geometry file has {', '.join(map(repr, names))}")
            key = f"{_AREAS}/{name}/Cells Minimum Elevation"
            if key not in gf:
                raise FlowFileError(f"{gpath}: area {name!r} has no 'Cells Minimum Elevation'")
            z = _read(gf, key, gpath)
            if counts[names.index(name)] != nreal:
                raise FlowFileError(f"{gpath}: area {name!r} has {counts[names.index(name)]} "
                                    f"cells, the plan {path} has {nreal}: not the plan's "
                                    "geometry")
            beds.append(z[:nreal].astype(np.float64) * factor)
        return np.concatenate(beds)


def _bed_from_terrain(tpath, geom, path):
    try:
        import rasterio
    except ImportError:
        raise FlowFileError(f"{path}: terrain = {str(tpath)!r} needs the package rasterio "
                            "(pip install rasterio)") from None
    tpath = Path(tpath)
    if not tpath.is_file():
        raise FlowFileError(f"{tpath}: terrain raster not found")
    mesh, fac = geom.mesh, geom.length_factor
    try:
        with rasterio.open(tpath) as r:
            x0, y0, x1, y1 = (np.asarray(mesh.bounds) / fac)
            win = rasterio.windows.from_bounds(x0, y0, x1, y1, r.transform).round_offsets() \
                .round_lengths()
            z = r.read(1, window=win, masked=True, boundless=True).astype(np.float64)
            tr = r.window_transform(win)
    except rasterio.errors.RasterioError as exc:
        raise FlowFileError(f"{tpath}: cannot read the terrain raster ({exc})") from None
    rows, cols = np.indices(z.shape)
    px = (tr.c + (cols + 0.5) * tr.a + (rows + 0.5) * tr.b) * fac
    py = (tr.f + (cols + 0.5) * tr.d + (rows + 0.5) * tr.e) * fac
    ok = ~np.ma.getmaskarray(z)
    face = mesh.locate(px[ok], py[ok])
    inside = face >= 0
    cell = geom.cell_of_face[face[inside]]
    zc = np.full(geom.n_cells, np.inf)
    np.minimum.at(zc, cell, z.data[ok][inside] * fac)
    empty = ~np.isfinite(zc)
    if np.any(empty):  # cells smaller than a pixel: the pixel at the cell's centroid
        cx = np.bincount(geom.cell_of_face, mesh.face_area * mesh.face_x, geom.n_cells)
        cy = np.bincount(geom.cell_of_face, mesh.face_area * mesh.face_y, geom.n_cells)
        cx, cy = cx[empty] / geom.cell_area[empty], cy[empty] / geom.cell_area[empty]
        det = tr.a * tr.e - tr.b * tr.d  # invert the affine transform (no rotation assumed)
        dx, dy = cx / fac - tr.c, cy / fac - tr.f
        cc, rr = (tr.e * dx - tr.b * dy) / det, (tr.a * dy - tr.d * dx) / det
        rr, cc = np.floor(rr).astype(int), np.floor(cc).astype(int)
        good = (rr >= 0) & (rr < z.shape[0]) & (cc >= 0) & (cc < z.shape[1])
        vals = np.full(rr.size, np.nan)
        vals[good] = np.where(ok[rr[good], cc[good]], z.data[rr[good], cc[good]] * fac, np.nan)
        zc[empty] = vals
    if not np.all(np.isfinite(zc)):
        bad = np.flatnonzero(~np.isfinite(zc))
        raise FlowFileError(f"{tpath}: the terrain raster does not cover {bad.size} cells of "
                            f"{path} (first {bad[:5].tolist()}): nodata or outside the raster")
    return zc


def _bed(f, rf, path, geom, bed, geometry, terrain):
    """Bed per cell (SI) and a sentence saying where it comes from."""
    if bed not in ("auto", "min_water_surface"):
        raise FlowFileError(f"{path}: option bed = {bed!r}: must be 'auto' or "
                            "'min_water_surface'")
    if bed == "min_water_surface":
        out = []
        for name, nreal in zip(geom.areas, geom.n_real, strict=True):
            ds = rf[f"{_SERIES}/2D Flow Areas/{name}/Water Surface"]
            low = np.full(nreal, np.inf)
            for k in range(ds.shape[0]):  # one output time at a time (bounded memory)
                try:
                    np.minimum(low, ds[k, :nreal], out=low)
                except OSError as exc:
                    raise FlowFileError(f"{rf.filename}: cannot read {ds.name!r}: the file is "
                                        f"truncated or damaged ({exc})") from None
            key = f"{_SUMMARY}/{name}/Minimum Water Surface"
            if key in f:
                np.minimum(low, _read(f, key, path)[0, :nreal], out=low)
            out.append(low * geom.length_factor)
        return np.concatenate(out), ("bed = 'min_water_surface': the lowest water surface the "
                                     "plan reports per cell (summary Minimum Water Surface and "
                                     "every output time): the bed where a cell went dry, above "
                                     "it elsewhere")
    keys = [f"{_AREAS}/{n}/Cells Minimum Elevation" for n in geom.areas]
    if all(k in f for k in keys):
        z = np.concatenate([_read(f, k, path)[:n] for k, n in zip(keys, geom.n_real, strict=True)])
        return z.astype(np.float64) * geom.length_factor, "Cells Minimum Elevation (plan)"
    if geometry is not None:
        return (_bed_from_geometry_file(geometry, geom, path),
                f"Cells Minimum Elevation of {geometry}")
    if terrain is not None:
        return _bed_from_terrain(terrain, geom, path), f"lowest pixel of {terrain} in each cell"
    missing = [n for n, k in zip(geom.areas, keys, strict=True) if k not in f]
    raise FlowFileError(f"{path}: no bed: the areas {missing} have no 'Cells Minimum "
                        "Elevation'; name its source with the option geometry = \"<the plan's "
                        "geometry .gNN.hdf>\" or terrain = \"<terrain raster>\" (or, knowingly, "
                        "bed = \"min_water_surface\")")


def _results_file(f, path, results):
    if results is not None:
        rf = _open_h5(results, "results file")
        if _SERIES + "/2D Flow Areas" not in rf:
            rf.close()
            raise FlowFileError(f"{results}: no HEC-RAS 2D time series (no {_SERIES!r}/2D Flow "
                                "Areas)")
        return rf, Path(results)
    if _SERIES + "/2D Flow Areas" not in f:
        ftype = "a geometry file" if "Results" not in f else "a plan without 2D time series"
        raise FlowFileError(f"{path}: no 2D results: {ftype} (no {_SERIES!r}/2D Flow Areas); "
                            "give the plan's output (*.pNN.hdf) or name the file holding the "
                            "time series with the option results = \"...\"")
    return f, Path(path)


def open_hecras(path, time_range=None, variables=None, dry_depth=1e-3, areas=None, bed="auto",
                geometry=None, terrain=None, results=None):
    """Open a HEC-RAS 2D plan output as a MeshFlowField (snapshots read lazily).

    Parameters
    ----------
    path : path
        HEC-RAS plan HDF (``*.pNN.hdf``) with 2D flow areas.
    time_range : (start, end), optional
        Only the snapshots in [start, end] (s since the first output time).
    variables : dict, optional
        Not used (HEC-RAS names its datasets itself); must be empty.
    dry_depth : float
        Depth (m) below which a face is dry.
    areas, bed, geometry, terrain, results
        See ``OPTIONS``.

    Returns
    -------
    MeshFlowField
        Times in seconds since the first output time; ``attrs`` holds ``time_reference``,
        ``crs_wkt``, the areas read and the bed's source.
    """
    from driftlog.flow import MeshFlowField

    from ._common import select_times

    if variables:
        raise FlowFileError(f"{path}: [flow] variables do not apply to HEC-RAS files (the "
                            f"reader knows its dataset names), got {sorted(variables)}")
    path = Path(path)
    f = _open_h5(path)
    rf = None
    try:
        geom = read_geometry(path, areas, f=f)
        rf, rpath = _results_file(f, path, results)
        for name in geom.areas:
            base = f"{_SERIES}/2D Flow Areas/{name}"
            for ds in ("Water Surface", "Face Velocity"):
                if f"{base}/{ds}" not in rf:
                    raise FlowFileError(f"{rpath}: area {name!r} has no {ds!r} time series "
                                        f"(looked for {base + '/' + ds!r})")
        times, epoch = read_time_axis(rf, rpath)
        nt = rf[f"{_SERIES}/2D Flow Areas/{geom.areas[0]}/Water Surface"].shape[0]
        if nt != times.size:
            raise FlowFileError(f"{rpath}: {nt} water-surface snapshots for {times.size} times")
        bed_cells, bed_source = _bed(f, rf, path, geom, bed, geometry, terrain)
        idx = select_times(times, time_range, str(rpath))
        name = f"HEC-RAS {path.name}"
        src = HecrasSnapshots(rf, rpath, geom, bed_cells, times[idx], idx, name)
        attrs = dict(geom.attrs, source="hecras", hecras_bed=bed_source,
                     hecras_results=str(rpath), hecras_split_cells=geom.n_split)
        if epoch is not None:
            attrs["time_reference"] = f"seconds since {epoch}"
        if "Plan Data/Plan Information" in f:
            plan = f["Plan Data/Plan Information"].attrs.get("Plan Name")
            if plan is not None:
                attrs["hecras_plan"] = _s(plan)
        if rf is not f:
            f.close()
        return MeshFlowField(geom.mesh, bed_cells[geom.cell_of_face], src, dry_depth, name=name,
                             attrs=attrs)
    except BaseException:
        if rf is not None and rf is not f:
            rf.close()
        if f.id.valid:
            f.close()
        raise


open = open_hecras  # the reader contract's name (module-level: ``hecras.open(path)``)


def describe(path) -> list[str]:
    """A few lines on a HEC-RAS file for ``driftlog info``."""
    path = Path(path)
    f = _open_h5(path)
    with f:
        names, counts = _area_table(f, path)
        factor, system = _units(f, path)
        lines = [f"HEC-RAS file ({_s(f.attrs.get('File Version', b'?'))}), {system}"]
        for n, c in zip(names, counts, strict=True):
            has_bed = f"{_AREAS}/{n}/Cells Minimum Elevation" in f
            lines.append(f"  2D area {n!r}: {c} cells" + ("" if has_bed else " (no bed)"))
        if _SERIES + "/2D Flow Areas" in f:
            t, epoch = read_time_axis(f, path)
            lines.append(f"  time series: {t.size} outputs over {t[-1] - t[0]:g} s"
                         + (f" from {epoch}" if epoch else ""))
        else:
            lines.append("  no 2D time series (geometry only)")
        return lines
