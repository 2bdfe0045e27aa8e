"""HEC-RAS 2D geometry (HEC-RAS 6.x HDF5): cell polygons, face normals and lengths, areas.

The mesh half of ``driftlog.adapters.hecras`` (see its docstring for the whole reader): each
cell's polygon from its faces, face points and perimeter points, convex cells as one mesh face,
the others split into triangles (ear clipping), several 2D flow areas in one mesh, US Customary
lengths converted to metres.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numba as nb
import numpy as np
import scipy.sparse as sp

from driftlog.errors import FlowFileError, MeshError

__all__ = ["FT", "MAX_SIDES", "AREAS", "HecrasGeometry", "read_geometry", "open_h5", "read_dataset",
           "area_table", "units", "foot", "projection_unit", "as_text", "HDF5_SIGNATURE",
           "check_projection"]

FT = 0.3048  # international foot in metres: US Customary lengths without a foot in the Projection
US_FT = 1200.0 / 3937.0  # US survey foot (State Plane coordinates in feet)
MAX_SIDES = 8  # cells with more nodes (perimeter points) are split into triangles

AREAS = "Geometry/2D Flow Areas"
HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"



def as_text(v) -> str:
    """An HDF5 attribute or string value as text."""
    if isinstance(v, np.ndarray) and v.size == 1:
        v = v.ravel()[0]
    if isinstance(v, (bytes, np.bytes_)):
        return v.decode("utf-8", "replace").strip()
    return str(v).strip()


def open_h5(path, what="HEC-RAS file"):
    import h5py

    p = Path(path)
    if not p.is_file():
        raise FlowFileError(f"{p}: {what} not found")
    with p.open("rb") as fh:
        head = fh.read(8)
    if head != HDF5_SIGNATURE:
        raise FlowFileError(f"{p}: not a HEC-RAS file (not HDF5: HEC-RAS 6 writes plan and "
                            "geometry results as HDF5, *.pNN.hdf / *.gNN.hdf)")
    try:
        return h5py.File(p, "r")
    except OSError as exc:
        msg = str(exc)
        why = "truncated or damaged" if "truncated" in msg or "eof" in msg else "unreadable"
        raise FlowFileError(f"{p}: {why} HDF5 file ({msg})") from None


def read_dataset(f, key, path):
    """A dataset's values; a damaged (truncated) file gives a FlowFileError."""
    try:
        return f[key][()]
    except KeyError:
        raise FlowFileError(f"{path}: dataset {key!r} is missing") from None
    except OSError as exc:
        raise FlowFileError(f"{path}: cannot read {key!r}: the file is truncated or damaged "
                            f"({exc})") from None


def area_table(f, path):
    """(names, real cell counts) of the 2D flow areas of an open HEC-RAS file."""
    if AREAS not in f:
        ftype = as_text(f.attrs.get("File Type", b""))
        kind = f"a {ftype!r} file" if ftype else "an HDF5 file"
        raise FlowFileError(f"{path}: not a HEC-RAS 2D file: {kind} without the group "
                            f"{AREAS!r} (no 2D flow area)")
    g = f[AREAS]
    if "Attributes" in g:
        att = read_dataset(f, AREAS + "/Attributes", path)
        names = [as_text(n) for n in att["Name"]]
        counts = [int(c) for c in att["Cell Count"]] if "Cell Count" in att.dtype.names else None
    else:
        names = [k for k in g if isinstance(g[k], type(g)) and "FacePoints Coordinate" in g[k]]
        counts = None
    if counts is None:  # real cells come first; virtual (ghost) cells have one face
        counts = []
        for n in names:
            info = read_dataset(f, f"{AREAS}/{n}/Cells Face and Orientation Info", path)
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
        Metres per file length unit (1 for SI; for US Customary the foot of the file's
        Projection, e.g. the US survey foot 0.3048006096, else the international foot 0.3048).
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


# a WKT unit: WKT1 UNIT["name", factor], WKT2 LENGTHUNIT["name", factor] (not ANGLEUNIT)
_WKT_UNIT = re.compile(r'\b(?:LENGTH)?UNIT\[\s*"([^"]*)"\s*,\s*([-+0-9.eE]+)')
_ANGULAR = re.compile(r"degree|radian|grad|gon|arc|second|minute", re.IGNORECASE)


def projection_unit(wkt):
    """(name, metres) of the last linear unit of a WKT projection, None without one.

    The last ``UNIT[...]`` (``LENGTHUNIT[...]`` in WKT2) that is not an angle: in a PROJCS the
    outermost one, the unit of the projected coordinates (the GEOGCS's degrees come before
    it).
    """
    found = [(name, float(value)) for name, value in _WKT_UNIT.findall(wkt or "")
             if not _ANGULAR.search(name)]
    if not found or not (found[-1][1] > 0 and np.isfinite(found[-1][1])):
        return None
    return found[-1]


def foot(f):
    """(metres per foot, in words) of a US Customary file: the Projection's foot, else 0.3048.

    HEC-RAS's coordinates are the projection's: a State Plane projection in US survey feet
    (``UNIT["Foot_US",0.3048006096012192]``) at x ~ 2e6 ft puts a point 1.2 m further than
    the international foot would.  A Projection whose unit is not a foot (or none) leaves the
    international foot, 0.3048 m.
    """
    wkt = as_text(f.attrs.get("Projection", b""))
    unit = projection_unit(wkt)
    if unit is not None and abs(unit[1] / FT - 1.0) < 1e-4:
        kind = ("the international foot" if abs(unit[1] / FT - 1.0) < 1e-9 else
                "the US survey foot" if abs(unit[1] / US_FT - 1.0) < 1e-9 else "the foot")
        return unit[1], f"1 ft = {unit[1]!r} m, {kind} of the Projection's UNIT[{unit[0]!r}]"
    why = (f"the Projection's unit {unit[0]!r} ({unit[1]!r} m) is not a foot" if unit
           else "the file names no projection unit")
    return FT, f"1 ft = {FT} m, the international foot ({why})"


def units(f, path):
    """(metres per length unit of the file, units system in words) of a HEC-RAS file."""
    system = as_text(f.attrs.get("Units System", b""))
    if system == "" and "Geometry" in f:
        si = as_text(f["Geometry"].attrs.get("SI Units", b""))
        system = "SI Units" if si.lower() == "true" else ("US Customary" if si else "")
    if system.lower().startswith("us"):
        factor, words = foot(f)
        return factor, f"US Customary ({words})"
    if system.lower().startswith("si") or system == "":
        return 1.0, system or "SI Units (assumed: no 'Units System' attribute)"
    raise FlowFileError(f"{path}: 'Units System' = {system!r} not understood (expected "
                        "'US Customary' or 'SI Units')")


def check_projection(f, path):
    """Refuse a file whose 'Projection' attribute (RAS Mapper's WKT) is a geographic CRS.

    HEC-RAS 2D computes in the projection's plane units; a file without the attribute (no
    projection set in RAS Mapper) is taken as projected.
    """
    from ._common import refuse_geographic_wkt

    proj = f.attrs.get("Projection")
    if proj is not None:
        refuse_geographic_wkt(as_text(proj), path, "attribute 'Projection'")


def _read_area(f, path, name, ncell, factor):
    """One 2D area: polygon nodes per cell, face normals and lengths, least-squares weights.

    (A function of its own so that its many temporaries are freed before the mesh is built.)
    """
    base = f"{AREAS}/{name}"
    fp = read_dataset(f, base + "/FacePoints Coordinate", path).astype(np.float64) * factor
    ffp = read_dataset(f, base + "/Faces FacePoint Indexes", path).astype(np.int64)
    info = read_dataset(f, base + "/Cells Face and Orientation Info", path).astype(np.int64)
    vals = read_dataset(f, base + "/Cells Face and Orientation Values", path).astype(np.int64)
    if f"{base}/Faces Perimeter Info" in f:
        pinfo = read_dataset(f, base + "/Faces Perimeter Info", path).astype(np.int64)
        pv = read_dataset(f, base + "/Faces Perimeter Values", path).astype(np.float64) * factor
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
        f = open_h5(path)
    try:
        names, counts = area_table(f, path)
        sel = _select_areas(names, areas, path)
        check_projection(f, path)
        factor, system = units(f, path)
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
        words = foot(f)[1] if factor != 1.0 else ""
        if words:  # which foot: 2 ppm is 1.2 m at State Plane coordinates of 2e6 ft
            attrs["import_notes"] = f"US Customary lengths converted to metres with {words}"
        proj = f.attrs.get("Projection")
        if proj is not None and as_text(proj):
            attrs["crs_wkt"] = as_text(proj)
            attrs["crs_note"] = (f"x, y are the projection's coordinates x {factor!r} (metres; "
                                 f"{words})" if words
                                 else "x, y are the projection's coordinates")
        return HecrasGeometry(mesh, cell_of_face[order], [names[i] for i in sel], sel,
                              np.asarray(cell_start), np.asarray(face_start),
                              [counts[i] for i in sel], cell_area, np.concatenate(normals),
                              np.concatenate(lengths), vx, vy, factor, attrs, int(split.size))
    finally:
        if own:
            f.close()
